"""Where the project's data files are: models/ and the packaged paper figures."""

from __future__ import annotations

import json
from functools import cache
from importlib import resources
from pathlib import Path

#: The repository's models/ folder (the package is installed editable from the checkout).
MODELS_DIR = Path(__file__).resolve().parent.parent / "models"


def model_path(name: str) -> Path:
    """Path of ``models/<name>``; ``FileNotFoundError`` naming it when absent."""
    p = MODELS_DIR / name
    if not p.exists():
        raise FileNotFoundError(f"model file {p} not found (is the package installed from a full checkout?)")
    return p


@cache
def paper_results() -> dict:
    """The paper's published figures (a copy of shared/paper_results.json shipped in the package)."""
    with resources.files("akc_drake.data").joinpath("paper_results.json").open(encoding="utf-8") as f:
        return json.load(f)
