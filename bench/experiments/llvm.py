"""The libLLVM Mitsuba 3's llvm variants run on, chosen once for every experiment.

Dr.Jit finds a libLLVM by itself, and on Debian 12 that is LLVM 15, whose back end aborts the
path integrator ("Cannot select fminimum"); LLVM 19 (``scripts/bootstrap.sh`` installs
``libllvm19``) runs it. ``DRJIT_LIBLLVM_PATH`` must be set before Dr.Jit starts its LLVM back
end, so the package sets it when imported, unless the environment already names one.
"""

from __future__ import annotations

import os
from pathlib import Path

LIBLLVM = Path("/usr/lib/x86_64-linux-gnu/libLLVM-19.so")


def use_llvm19() -> str | None:
    """Point ``DRJIT_LIBLLVM_PATH`` at :data:`LIBLLVM` when unset and the library exists; the path in use."""
    if "DRJIT_LIBLLVM_PATH" not in os.environ and LIBLLVM.exists():
        os.environ["DRJIT_LIBLLVM_PATH"] = str(LIBLLVM)
    return os.environ.get("DRJIT_LIBLLVM_PATH")
