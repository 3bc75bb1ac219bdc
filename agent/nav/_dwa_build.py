"""Build-time only: cffi's API-mode builder of ``tlfleet.agent.nav._dwa``, the DWA's per-sample
arithmetic in C (``agent/nav/dwa_kernel.c``; ``setup.py`` names it in ``cffi_modules``).
``dwa.py`` uses the built module when it is there and the same arithmetic in numpy when it is not
(no C compiler at install time); the two are equal to the last bit where numpy's sin, cos and
exp are libm's (tests/nav/test_nav_dwa_native.py)."""

from pathlib import Path

from cffi import FFI

HERE = Path(__file__).resolve().parent
HEADER = (HERE / "dwa_kernel.h").read_text()

ffibuilder = FFI()
ffibuilder.cdef(HEADER)
ffibuilder.set_source(
    "tlfleet.agent.nav._dwa",
    '#include "dwa_kernel.h"\n',
    sources=[str(Path("agent") / "nav" / "dwa_kernel.c")],
    include_dirs=[str(Path("agent") / "nav")],
    libraries=["m"],
    # no fused multiply-adds and no builtin rewrites: the numpy form's operations exactly
    extra_compile_args=["-O2", "-ffp-contract=off", "-fno-builtin", "-fno-fast-math"],
)

if __name__ == "__main__":
    ffibuilder.compile(verbose=True)
