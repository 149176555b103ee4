"""The studies' CSV files: rows of numbers written with exactly the study's columns, and read back."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from ..io.manifest import atomic_path


def write_csv(path, rows: list[dict], columns) -> Path:
    """Write rows with exactly `columns`, atomically, floats to 6 significant digits."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as f:
        csv.writer(f).writerows([columns, *([_cell(row[c]) for c in columns] for row in rows)])
    return path


def read_csv(path) -> list[dict]:
    """Rows of a study CSV, numbers as floats."""
    with open(path, newline="") as f:
        return [{key: _number(value) for key, value in row.items()} for row in csv.DictReader(f)]


def _cell(value):
    return f"{float(value):.6g}" if isinstance(value, (float, np.floating)) else value


def _number(text: str):
    try:
        return float(text)
    except ValueError:
        return text
