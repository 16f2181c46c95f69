"""Rows of results printed as an aligned text table (the demo, sim-train, the benchmarks)."""

from __future__ import annotations

import math
from typing import Any


def column_format(values: list[Any]) -> str:
    """The format of a column's floats: as many decimals for each as give its largest 4
    significant digits (PSNRs 43.10, 37.12, 40.00, not 43.1, 37.12, 40), where they all lie in
    [0.001, 1e6) within a factor 1000 of each other; else 4 significant digits each (0.0123 ms
    beside 2500 ms would read 0)."""
    sizes = [abs(v) for v in values if isinstance(v, float) and math.isfinite(v) and v != 0]
    if not sizes or min(sizes) < 1e-3 or max(sizes) >= 1e6 or max(sizes) >= 1e3 * min(sizes):
        return ".4g"
    return f".{max(0, 3 - math.floor(math.log10(max(sizes))))}f"


def print_table(rows: list[dict[str, Any]], columns: list[str] | None = None) -> None:
    """Print rows of dicts as an aligned text table, a column's floats to the same decimals."""
    if not rows:
        return
    columns = columns or list(rows[0])
    formats = [column_format([row.get(c) for row in rows]) for c in columns]

    def fmt(value: Any, spec: str) -> str:
        return format(value, spec) if isinstance(value, float) else str(value)

    cells = [[fmt(row.get(c, ""), f) for c, f in zip(columns, formats)] for row in rows]
    widths = [max(len(c), *(len(r[i]) for r in cells)) for i, c in enumerate(columns)]
    print("  ".join(c.rjust(w) for c, w in zip(columns, widths)))
    for r in cells:
        print("  ".join(v.rjust(w) for v, w in zip(r, widths)))
