"""Quality presets: one word that sets every speed/accuracy knob of the solver.

Each knob also has its own flag; a flag given explicitly wins over the preset.
Mesh refinement is relative to the scene's size, so a preset means the same in
millimetres and in metres.
"""

from __future__ import annotations

from radiosity.formats.errors import InputError

QUALITIES = ("draft", "medium", "high")
DEFAULT_QUALITY = "draft"

# maximum edge length of the solver mesh, as a fraction of the scene's bounding-box diagonal
MAX_EDGE_FRACTION = {"draft": 1 / 24, "medium": 1 / 40, "high": 1 / 64}


def max_edge(scene, quality=DEFAULT_QUALITY, explicit=None):
    """The refinement edge length: ``explicit`` if given, else the preset's fraction
    of the scene diagonal. Returns (length, how it was chosen)."""
    if explicit is not None:
        if not explicit > 0:
            raise InputError(f"--max-edge must be positive, got {explicit:g}")
        return float(explicit), "--max-edge"
    if quality not in QUALITIES:
        raise InputError(f"unknown quality {quality!r}; choose one of {', '.join(QUALITIES)}")
    fraction = MAX_EDGE_FRACTION[quality]
    return scene.diagonal * fraction, f"{quality} preset: diagonal / {round(1 / fraction)}"
