"""The one part of the build ``pyproject.toml`` cannot say: the optional C accelerators.

* ``sim._tracking`` (``sim/tracking.c``, built by cffi from ``sim/_tracking_build.py``) makes the
  simulator's physics step several times cheaper (issue 17);
* ``agent.nav._dwa`` (``agent/nav/dwa_kernel.c``, from ``agent/nav/_dwa_build.py``) does the
  LTL agents' DWA rollouts and costs (issue 17);
* ``agent.protocol._wire`` (``agent/protocol/wire_kernel.c``, a CPython extension: it builds the
  messages itself) decodes the per-tick ``MocapFrame`` and ``Command`` (issue 17).

All are optional: without a C compiler the build warns and the package installs without them,
and ``sim.world``, ``agent.nav.dwa`` and ``agent.protocol.fast_paths`` run the same work in
Python, with the same results to the last bit."""

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext


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


setup(cffi_modules=["sim/_tracking_build.py:ffibuilder", "agent/nav/_dwa_build.py:ffibuilder"],
      ext_modules=[Extension("agent.protocol._wire", ["agent/protocol/wire_kernel.c"],
                             extra_compile_args=["-O2"])],
      cmdclass={"build_ext": OptionalBuildExt})
