"""The studies' CSV files: rows of numbers written with exactly the study's columns, and read back."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np


def write_csv(path, rows: list[dict], columns) -> Path:
    """Write rows with exactly `columns`, atomically (a temporary file renamed into place)."""
    from ..io.manifest import atomic_path

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(columns)
        for row in rows:
            writer.writerow([csv_cell(row[c]) for c in columns])
    return path


def read_csv(path) -> list[dict]:
    """Rows of a study CSV, numbers as floats."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    for row in rows:
        for key, value in row.items():
            try:
                row[key] = float(value)
            except ValueError:
                pass
    return rows


def csv_cell(value):
    """A CSV cell: a float to 6 significant digits, anything else as it is."""
    if isinstance(value, (float, np.floating)):
        return f"{float(value):.6g}"
    return value
