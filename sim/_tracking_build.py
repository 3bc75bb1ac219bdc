"""Build-time only: cffi's API-mode builder of ``tlfleet.sim._tracking``, the C tracking law
(``sim/tracking.c``; ``setup.py`` names it in ``cffi_modules``). ``world.py`` uses the built
module when it is there and the same law in Python when it is not (no C compiler at install
time); the two are equal to the last bit (tests/sim/test_sim_tracking_native.py)."""

from pathlib import Path

from cffi import FFI

HERE = Path(__file__).resolve().parent
HEADER = (HERE / "tracking.h").read_text()

ffibuilder = FFI()
ffibuilder.cdef(HEADER)
ffibuilder.set_source(
    "tlfleet.sim._tracking",
    '#include "tracking.h"\n',
    sources=[str(Path("sim") / "tracking.c")],
    include_dirs=[str(Path("sim"))],
    libraries=["m"],
    # no fused multiply-adds, no cos+sin → sincos: the Python law's operations exactly
    extra_compile_args=["-O2", "-ffp-contract=off", "-fno-builtin", "-fno-fast-math"],
)

if __name__ == "__main__":
    ffibuilder.compile(verbose=True)
