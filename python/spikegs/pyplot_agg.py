"""matplotlib's pyplot drawing to files (Agg), whatever MPLBACKEND says."""

from __future__ import annotations

import os


def pyplot():
    """matplotlib.pyplot on the Agg backend. MPLBACKEND is set aside while matplotlib loads: one
    it does not know (`inline`, meant for Jupyter) raised ValueError at the import, after a run
    had trained, and its curve.png was lost (the figures are files, whatever backend it names)."""
    saved = os.environ.pop("MPLBACKEND", None)
    try:
        import matplotlib
    finally:
        if saved is not None:
            os.environ["MPLBACKEND"] = saved
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt
