"""Shared helpers of the example scripts: output folder, PNG writing, a plain-text table."""

from __future__ import annotations

from pathlib import Path
import sys

import numpy as np

ROOT = Path(__file__).resolve().parent
OUT = ROOT / "out"
sys.path.insert(0, str(ROOT.parent))


def out_path(name: str) -> Path:
    """examples/out/<name>, creating the folder."""
    OUT.mkdir(exist_ok=True)
    return OUT / name


def save_gray(path, img) -> None:
    """Write an (H, W) float image in [0, 1] as an 8-bit PNG."""
    import cv2
    cv2.imwrite(str(path), np.clip(np.rint(np.asarray(img) * 255), 0, 255).astype(np.uint8))


def quantise(img) -> np.ndarray:
    """What an 8-bit PNG keeps of a float image in [0, 1]."""
    return np.clip(np.rint(np.asarray(img) * 255), 0, 255) / 255.0


def table(header, rows) -> str:
    """A GitHub-markdown table of formatted rows."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(lines)
