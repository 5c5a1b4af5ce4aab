"""Where the project's data files are: models/ and the packaged paper figures."""

from __future__ import annotations

import json
from functools import cache
from importlib import resources
from pathlib import Path

#: The package's models/ folder (installed with the package as package data).
MODELS_DIR = Path(__file__).resolve().parent / "models"


def model_path(name: str) -> Path:
    """Path of ``models/<name>``; ``FileNotFoundError`` naming it when absent."""
    p = MODELS_DIR / name
    if not p.exists():
        raise FileNotFoundError(
            f"model file {p} not found (the package installation is incomplete: reinstall akc-drake)"
        )
    return p


@cache
def paper_results() -> dict:
    """The paper's published figures (a copy of shared/paper_results.json shipped in the package)."""
    with resources.files("akc_drake.data").joinpath("paper_results.json").open(encoding="utf-8") as f:
        return json.load(f)
