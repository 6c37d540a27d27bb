#!/usr/bin/env bash
# The README's first command on a new Debian machine, timed from nothing: a minimal Debian
# (debootstrap --variant=minbase, the release of this machine) in a scratch folder, a clone of
# this repository in it, then `bash scripts/demo.sh` inside (apt-get update and install, the
# build, the pictures). Prints the seconds from the start to each milestone and the CPU time.
# Usage (root; needs debootstrap):  bash bench/fresh_demo.sh [COMMIT] [WORKDIR]
#   COMMIT   what to clone (default HEAD); WORKDIR default /tmp/wavebrdf-fresh (removed first).
# The minimal system itself is made before the clock starts (like a machine's installation);
# its network is the host's, and its apt sources are the release's main, updates and security.
set -euo pipefail
cd "$(dirname "$0")/.."
commit="${1:-HEAD}"
work="${2:-/tmp/wavebrdf-fresh}"
[ "$(id -u)" -eq 0 ] || { echo "fresh_demo: run as root (debootstrap, chroot, mount)" >&2; exit 2; }
command -v debootstrap >/dev/null || { echo "fresh_demo: debootstrap is not installed (apt-get install debootstrap)" >&2; exit 2; }
. /etc/os-release
release="${VERSION_CODENAME:?fresh_demo: /etc/os-release names no VERSION_CODENAME}"
root="$work/root"
rm -rf "$work"
mkdir -p "$work"
debootstrap --variant=minbase "$release" "$root" http://deb.debian.org/debian >"$work/debootstrap.log"
cat >"$root/etc/apt/sources.list" <<EOF
deb http://deb.debian.org/debian $release main
deb http://deb.debian.org/debian $release-updates main
deb http://deb.debian.org/debian-security $release-security main
EOF
cp /etc/resolv.conf "$root/etc/resolv.conf"
git clone -q . "$root/root/wavebrdf"
git -C "$root/root/wavebrdf" checkout -q "$commit"
mount -t proc proc "$root/proc"
mount --bind /dev "$root/dev"
mount --bind /dev/pts "$root/dev/pts"
watcher=""
cleanup() {
    [ -z "$watcher" ] || kill "$watcher" 2>/dev/null || true
    umount "$root/dev/pts" "$root/dev" "$root/proc" 2>/dev/null || true
}
trap cleanup EXIT

# Milestones: the compiler unpacked, the build configured, the CLI linked, each picture written.
marks=(usr/bin/cmake root/wavebrdf/build/CMakeCache.txt root/wavebrdf/build/bin/wavebrdf
       root/wavebrdf/out/demo/slice.png root/wavebrdf/out/demo/image.png root/wavebrdf/out/invert/report.png)
start=$(date +%s.%N)
(
    seen=()
    while sleep 0.5; do
        for m in "${marks[@]}"; do
            case " ${seen[*]-} " in *" $m "*) continue ;; esac
            if [ -e "$root/$m" ]; then
                seen+=("$m")
                printf '%7.1f s  %s  (load %s)\n' "$(awk -v a="$(date +%s.%N)" -v b="$start" 'BEGIN { print a - b }')" "$m" "$(cut -d' ' -f1-3 /proc/loadavg)"
            fi
        done
    done
) >"$work/marks.txt" &
watcher=$!
echo "fresh_demo: $(git rev-parse --short "$commit") in a new $release, load $(cut -d' ' -f1-3 /proc/loadavg)"
/usr/bin/time -f '%e s wall, %U s user, %S s system' -o "$work/time.txt" \
    chroot "$root" /usr/bin/env -i HOME=/root PATH=/usr/sbin:/usr/bin:/sbin:/bin LANG=C.UTF-8 \
    bash -c 'cd /root/wavebrdf && bash scripts/demo.sh' >"$work/demo.log" 2>&1
sleep 1
cat "$work/marks.txt"
echo "demo.sh: $(cat "$work/time.txt"); load at the end $(cut -d' ' -f1-3 /proc/loadavg)"
grep -E 'Start-Date|End-Date' "$root/var/log/apt/history.log" | sed 's/^/apt: /'
