#!/usr/bin/env bash
# Times `wavebrdf genbrdf` against the reference program genBrdf (Yan et al. 2018's public
# release, built separately by the user; none of its code is in this repository): now the
# `table` part of bench/speed.sh (all five models and the README example, footprint at the
# centre). Usage:
#   GENBRDF=/path/to/genBrdf bash bench/compare_genbrdf.sh [runs]
# The cases of bench/results/2026-11-21-epyc-2core.md are this script as of commit 9fbfbb6.
set -euo pipefail
exec bash "$(dirname "$0")/speed.sh" --part table --runs "${1:-5}"
