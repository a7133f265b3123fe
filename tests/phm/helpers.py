"""Shared test helpers: write CSV logs, synthetic fade and discharge curves."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
EXAMPLES = REPO / "examples" / "phm"


def write_csv(path: Path, header: str, rows: Iterable[Sequence[object]],
              comments: Sequence[str] = ()) -> Path:
    """A CSV file with optional ``#`` comment lines before the header."""
    lines = [f"# {c}" for c in comments] + [header]
    lines += [",".join(str(v) for v in row) for row in rows]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def cycles_csv(path: Path, cycles: np.ndarray, capacity: np.ndarray) -> Path:
    return write_csv(path, "cycle,capacity_ah", zip(cycles.tolist(), capacity.tolist(),
                                                    strict=True))


def knee_curve(n: np.ndarray, a: float, b1: float, b2: float, nk: float) -> np.ndarray:
    return a - b1 * np.minimum(n, nk) - b2 * np.maximum(n - nk, 0.0)
