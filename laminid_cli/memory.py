"""How much memory this process may use, for refusing work up front instead of dying in it.

Used by the mesh check (:func:`laminid_cli.fe.mesh.check_mesh_memory`) and the RFP fitter
(:func:`laminid_cli.frf.rfp.find_modes`).
"""

from __future__ import annotations

import os


def available_memory_bytes() -> float | None:
    """Memory this process may still use: MemAvailable (Linux), else physical memory; capped by
    the address-space limit (``ulimit -v``). None when unknown."""
    found = None
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    found = float(line.split()[1]) * 1024
                    break
    except OSError:
        pass
    if found is None:
        try:
            found = float(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
        except (ValueError, OSError, AttributeError):
            found = None
    try:
        import resource

        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
        if soft != resource.RLIM_INFINITY and soft > 0:
            found = float(soft) if found is None else min(found, float(soft))
    except (ImportError, ValueError, OSError):
        pass
    return found


def format_bytes(n: float) -> str:
    """``71.8 GB``, ``250 MB`` (decimal units)."""
    return f"{n / 1e9:.3g} GB" if n >= 1e9 else f"{n / 1e6:.3g} MB"
