"""The one part of the build ``pyproject.toml`` cannot say: the optional C tracking law.

``sim._tracking`` (``sim/tracking.c``, built by cffi from ``sim/_tracking_build.py``) makes the
simulator's physics step several times cheaper (issue 17). It is optional: without a C compiler
the build warns and the package installs without it, and ``sim.world`` runs the same law in
Python, with the same results to the last bit."""

from setuptools import setup
from setuptools.command.build_ext import build_ext


class OptionalBuildExt(build_ext):
    """``build_ext`` that warns instead of failing: the extension is an accelerator."""

    def run(self) -> None:
        try:
            super().run()
        except Exception as exc:  # no compiler, no headers: install the pure-Python law
            self.warn(f"tlfleet: the C tracking law was not built ({exc}); the simulator "
                      "will run its Python law (same results, slower)")

    def build_extension(self, ext) -> None:
        try:
            super().build_extension(ext)
        except Exception as exc:
            self.warn(f"tlfleet: building {ext.name} failed ({exc}); the simulator will run "
                      "its Python law (same results, slower)")


setup(cffi_modules=["sim/_tracking_build.py:ffibuilder"],
      cmdclass={"build_ext": OptionalBuildExt})
