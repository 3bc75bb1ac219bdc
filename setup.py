"""What ``pyproject.toml`` cannot say: the package layout and the optional C accelerators.

**Layout.** Everything installs under one import package, ``tlfleet``, whose folder is the
repository's root: ``agent/`` is ``tlfleet.agent``, ``bus/`` is ``tlfleet.bus``, and so on for
``sim/``, ``coordinator/`` and ``cli/`` (``package_dir = {"tlfleet": "."}``). Only those five
folders and the root's ``__init__.py`` are packages of the distribution; ``tests/``, ``bench/``
and ``docker/`` beside them are not installed. ``scenarios/*.toml`` are installed as data, as
``tlfleet/scenarios/`` (``tlfleet run scenario1`` finds them by name:
``tlfleet.agent.scenario.bundled``).

**Stable ABI.** Every extension is built against CPython's limited API of 3.11 (cffi's two by
cffi itself, ``_wire`` by ``py_limited_api``), so the wheel is tagged ``cp311-abi3`` and one
wheel serves every CPython from 3.11 on; ``make dist`` then gives it a manylinux tag
(``auditwheel repair``).

**Accelerators.** All are optional: without a C compiler the build warns and the package installs
without them, and ``tlfleet.sim.world``, ``tlfleet.agent.nav.dwa`` and
``tlfleet.bus.protocol.fast_paths`` run the same work in Python, with the same results to the
last bit.

* ``tlfleet.sim._tracking`` (``sim/tracking.c``, built by cffi from ``sim/_tracking_build.py``)
  makes the simulator's physics step several times cheaper;
* ``tlfleet.agent.nav._dwa`` (``agent/nav/dwa_kernel.c``, from ``agent/nav/_dwa_build.py``) does
  the LTL agents' DWA rollouts and costs;
* ``tlfleet.bus.protocol._wire`` (``bus/protocol/wire_kernel.c``, a CPython extension: it builds
  the messages itself) decodes the per-tick ``MocapFrame`` and ``Command``.
"""

from setuptools import Extension, find_packages, setup
from setuptools.command.build_ext import build_ext
from setuptools.command.build_py import build_py

LAYER_FOLDERS = ("agent", "bus", "sim", "coordinator", "cli")
LIMITED_API = "0x030B0000"  # CPython 3.11, the oldest Python tlfleet supports (pyproject.toml)


class OptionalBuildExt(build_ext):
    """``build_ext`` that warns instead of failing: the extension is an accelerator."""

    def run(self) -> None:
        try:
            super().run()
        except Exception as exc:  # no compiler, no headers: install the pure-Python law
            self.warn(f"tlfleet: the C accelerators were not built ({exc}); the simulator, "
                      "the DWA and the codec will run their Python forms (same results, slower)")

    def build_extension(self, ext) -> None:
        try:
            super().build_extension(ext)
        except Exception as exc:
            self.warn(f"tlfleet: building {ext.name} failed ({exc}); its Python form will run "
                      "instead (same results, slower)")


class BuildPy(build_py):
    """``build_py`` that leaves this file out of the ``tlfleet`` package: the root is the package's
    folder, and the build script is not one of its modules."""

    def find_package_modules(self, package: str, package_dir: str) -> list[tuple[str, str, str]]:
        return [module for module in super().find_package_modules(package, package_dir)
                if (module[0], module[1]) != ("tlfleet", "setup")]


found = find_packages(include=[*LAYER_FOLDERS, *(f"{folder}.*" for folder in LAYER_FOLDERS)])
# tlfleet.scenarios: a folder of data (no __init__.py), installed with its *.toml (package-data
# in pyproject.toml)
setup(packages=["tlfleet", *(f"tlfleet.{package}" for package in found), "tlfleet.scenarios"],
      package_dir={"tlfleet": "."},
      cffi_modules=["sim/_tracking_build.py:ffibuilder", "agent/nav/_dwa_build.py:ffibuilder"],
      ext_modules=[Extension("tlfleet.bus.protocol._wire", ["bus/protocol/wire_kernel.c"],
                             extra_compile_args=["-O2"], py_limited_api=True,
                             define_macros=[("Py_LIMITED_API", LIMITED_API)])],
      options={"bdist_wheel": {"py_limited_api": "cp311"}},
      cmdclass={"build_ext": OptionalBuildExt, "build_py": BuildPy})
