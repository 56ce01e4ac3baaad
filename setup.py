"""The `lancer` module for pip: CMake configures this tree in the build directory and builds the module's
target alone (`lancer_python`), which setuptools then installs. The build needs what scripts/deps.sh
installs (a C++20 compiler, CMake, pybind11, oneTBB, assimp, libpng, OpenEXR)."""
import os
import pathlib
import shutil
import subprocess
import sys

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = pathlib.Path(__file__).resolve().parent


class CMakeBuild(build_ext):
    def build_extension(self, ext):
        build_dir = pathlib.Path(self.build_temp).resolve() / "cmake"
        configure = ["cmake", "-S", str(ROOT), "-B", str(build_dir), "-DCMAKE_BUILD_TYPE=Release",
                     f"-DPython3_EXECUTABLE={sys.executable}", "-DLANCER_BUILD_PYTHON=ON",
                     "-DLANCER_BUILD_TESTS=OFF", "-DLANCER_BUILD_BENCH=OFF", "-DLANCER_BUILD_APPS=OFF",
                     "-DLANCER_CUDA=OFF"]
        subprocess.run(configure, check=True)
        jobs = str(os.cpu_count() or 1)
        subprocess.run(["cmake", "--build", str(build_dir), "--target", "lancer_python", "-j", jobs], check=True)
        built = next((build_dir / "python").glob("lancer*.so"))
        target = pathlib.Path(self.get_ext_fullpath(ext.name))
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(built, target)
        # The type stubs, beside the module and as the stub-only package lancer-stubs (python/CMakeLists.txt).
        shutil.copyfile(build_dir / "python" / "lancer.pyi", target.with_name("lancer.pyi"))
        shutil.copytree(build_dir / "python" / "lancer-stubs", target.with_name("lancer-stubs"), dirs_exist_ok=True)


(ROOT / "build-python").mkdir(exist_ok=True)
# The module alone: no Python packages to discover (src/ holds C++). setuptools' files go under
# build-python/, not build/, CMake's release tree (the README's).
setup(ext_modules=[Extension("lancer", sources=[])], cmdclass={"build_ext": CMakeBuild}, packages=[],
      py_modules=[], options={"build": {"build_base": "build-python"}, "egg_info": {"egg_base": "build-python"}})
