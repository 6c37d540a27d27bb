"""setuptools build of the Python package `wavebrdf`: the extension wavebrdf._core is built by
the project's own CMake (target wavebrdf_python) in setuptools' temporary build directory, then
placed in the package next to the pure-Python modules of python/wavebrdf. Metadata, extras and
the version (the file VERSION) are in pyproject.toml.

    python3 -m venv --system-site-packages VENV
    VENV/bin/pip install --no-build-isolation .

Environment: CMAKE_ARGS (extra CMake arguments, shell-quoted, given after ours so they win,
e.g. CMAKE_ARGS="-DWAVEBRDF_NATIVE=OFF" for a wheel meant for other machines),
CMAKE_BUILD_PARALLEL_LEVEL (build jobs; default: the cores this process may use). ccache is
used when it is on PATH. WAVEBRDF_PIP_BUILD_DIR: setuptools' build directory (default
build-pip/; not build/, which is the CMake build tree of docs/architecture.md).
WAVEBRDF_PIP_CMAKE_DIR: the CMake build directory itself (default <build_temp>/cmake); one at
the depth of build/ (e.g. <checkout>/build-pip) lets ccache reuse build/'s compiled library,
since ccache (base_dir) compares paths relative to the build directory.
"""
import glob
import os
import shlex
import shutil
import subprocess
import sys

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

try:
    from setuptools.command.build import build
except ImportError:  # setuptools < 62
    from distutils.command.build import build

ROOT = os.path.dirname(os.path.abspath(__file__))


class CMakeExtension(Extension):
    """An extension built by a CMake target of this project (no sources of its own here)."""

    def __init__(self, name, target):
        super().__init__(name, sources=[])
        self.target = target


def cmake_arguments():
    """The configure arguments: every option we rely on is given explicitly, so the build does
    not depend on the project's defaults (which differ for a top-level build and a consumer)."""
    args = [
        "-DCMAKE_BUILD_TYPE=Release",
        "-DPython_EXECUTABLE=" + sys.executable,
        "-DWAVEBRDF_BUILD_PYTHON=ON",
        "-DWAVEBRDF_BUILD_TESTS=OFF",
        "-DWAVEBRDF_BUILD_BENCH=OFF",
        "-DWAVEBRDF_BUILD_FUZZERS=OFF",
        "-DWAVEBRDF_SANITIZE=OFF",
        # Built on the machine it is installed on: optimise for it (CMAKE_ARGS can turn it off).
        "-DWAVEBRDF_NATIVE=ON",
        # A fresh build compiles in batches (each parses the headers once), as scripts/setup.sh's
        # build/ does: with the same flags, ccache then reuses what build/ compiled.
        "-DWAVEBRDF_UNITY_BUILD=ON",
    ]
    if shutil.which("ccache"):
        args += ["-DCMAKE_CXX_COMPILER_LAUNCHER=ccache", "-DCMAKE_C_COMPILER_LAUNCHER=ccache"]
    args += shlex.split(os.environ.get("CMAKE_ARGS", ""))
    return args


def build_jobs():
    level = os.environ.get("CMAKE_BUILD_PARALLEL_LEVEL", "")
    if level.isdigit() and int(level) > 0:
        return level
    try:
        return str(len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return str(os.cpu_count() or 1)


class cmake_build_ext(build_ext):
    """Configures the CMake project in build_temp/cmake, builds each extension's target and
    copies the module it made to where setuptools packages it (the package itself for
    `pip install -e`)."""

    def build_extension(self, ext):
        if not isinstance(ext, CMakeExtension):
            return super().build_extension(ext)
        if shutil.which("cmake") is None:
            raise RuntimeError("cmake is not on PATH; the wavebrdf extension is built with CMake >= 3.20")
        build_dir = os.path.abspath(os.environ.get("WAVEBRDF_PIP_CMAKE_DIR") or os.path.join(self.build_temp, "cmake"))
        os.makedirs(build_dir, exist_ok=True)
        subprocess.run(["cmake", "-S", ROOT, "-B", build_dir] + cmake_arguments(), check=True)
        subprocess.run(["cmake", "--build", build_dir, "--target", ext.target, "-j", build_jobs()], check=True)
        # python/CMakeLists.txt puts the module in <build>/python/wavebrdf.
        leaf = ext.name.split(".")[-1]
        built = sorted(glob.glob(os.path.join(build_dir, "python", "wavebrdf", leaf + ".*so")))
        if len(built) != 1:
            raise RuntimeError("expected one %s module in %s/python/wavebrdf; found %s" % (leaf, build_dir, built))
        destination = self.get_ext_fullpath(ext.name)
        os.makedirs(os.path.dirname(os.path.abspath(destination)), exist_ok=True)
        shutil.copyfile(built[0], destination)
        # The MPI and HDF5 plugins (src/core/plugin.h), where the module looks first: beside it.
        for plugin in sorted(glob.glob(os.path.join(build_dir, "lib*", "wavebrdf", "libwavebrdf_*.so"))):
            shutil.copyfile(plugin, os.path.join(os.path.dirname(os.path.abspath(destination)), os.path.basename(plugin)))


class build_outside_cmake_tree(build):
    """setuptools' build directory: $WAVEBRDF_PIP_BUILD_DIR, else build-pip/ (not build/, the
    CMake build tree). The CMake build inside it is reused by the next install."""

    def initialize_options(self):
        super().initialize_options()
        self.build_base = os.environ.get("WAVEBRDF_PIP_BUILD_DIR") or "build-pip"


setup(
    ext_modules=[CMakeExtension("wavebrdf._core", target="wavebrdf_python")],
    cmdclass={"build_ext": cmake_build_ext, "build": build_outside_cmake_tree},
    zip_safe=False,
)
