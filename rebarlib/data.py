"""Sample designs and captures shared by tests, docstrings, notebooks and benchmarks."""

from __future__ import annotations

from pathlib import Path

from ._checks import RebarInputError
from ._design import Design, design_from_dict, load_design

__all__ = ["paper_design", "site_design", "examples_dir", "example_slab", "example_capture"]

_PAPER = {
    "slab": {"id": "PAPER", "location": "laboratory mesh (the paper's experiment)"},
    "design": {
        "cover_mm": 20,
        "layer_distance_mm": 85,
        "thickness_mm": 180,
        "lower": {"diameter_mm": 14, "spacing_mm": 200},
        "upper": {"diameter_mm": 12, "spacing_mm": 200},
    },
}
_SITE = {
    "slab": {"id": "SITE", "location": "site-like slab (the paper's site capture)"},
    "design": {
        "cover_mm": 15,
        "layer_distance_mm": 54,
        "thickness_mm": 110,
        "lower": {"diameter_mm": 8, "spacing_mm": 150},
        "upper": {"diameter_mm": 8, "spacing_mm": 150},
    },
}


def paper_design(*, cover_mm: float = 20, **design_overrides) -> Design:
    """The paper's experiment: lower Φ14, upper Φ12, spacing 200, layer distance 85 mm.

    Examples
    --------
    >>> paper_design(cover_mm=15).cover_mm
    15.0
    """
    data = {"slab": dict(_PAPER["slab"]), "design": {**_PAPER["design"], "cover_mm": cover_mm, **design_overrides}}
    return design_from_dict(data, source="paper_design()")


def site_design(**design_overrides) -> Design:
    """The paper's site capture: Φ8 bars at 150 mm, cover 15 mm, layer distance 54 mm."""
    data = {"slab": dict(_SITE["slab"]), "design": {**_SITE["design"], **design_overrides}}
    return design_from_dict(data, source="site_design()")


def examples_dir() -> Path:
    """The ``examples/`` folder of a source checkout."""
    path = Path(__file__).resolve().parent.parent / "examples"
    if not path.is_dir():
        raise RebarInputError(
            f"{path}: the examples folder ships with the source checkout; "
            "clone the repository to use the sample captures"
        )
    return path


def example_slab(name: str = "paper_slab") -> tuple[Path, Design]:
    """Folder and design of a shipped example slab (``paper_slab`` or ``site_slab``)."""
    folder = examples_dir() / name
    if not folder.is_dir():
        names = sorted(p.name for p in examples_dir().iterdir() if p.is_dir())
        raise RebarInputError(f"example slab {name!r} not found; available: {names}")
    return folder, load_design(folder / "design.toml")


def example_capture(slab: str = "paper_slab", capture: str = "B_500") -> Path:
    """Folder of one shipped example capture."""
    folder = example_slab(slab)[0] / capture
    if not folder.is_dir():
        raise RebarInputError(f"example capture {slab}/{capture} not found")
    return folder
