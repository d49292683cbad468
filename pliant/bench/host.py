"""The host a timing was taken on (``pliant bench`` records it before and after)."""

from __future__ import annotations

import os
import platform


def host() -> dict:
    """The host a timing was taken on: CPU model, cores and the load average, so that a reader
    can tell a slower host or a busy one from a slower Pliant (ratios against SOFA's figures,
    taken on another day, hold only on a host as fast and as quiet as theirs; SPEC §5)."""
    model = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as fh:
            names = [ln.split(":", 1)[1].strip() for ln in fh if ln.startswith("model name")]
        model = names[0] if names else model
    except OSError:
        pass
    load = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    return {
        "machine": platform.platform(),
        "cpu_model": model,
        "cpus": os.cpu_count(),
        "load_average_1_5_15_min": [round(x, 2) for x in load],
    }
