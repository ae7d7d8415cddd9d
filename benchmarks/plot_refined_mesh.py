"""The floor of cornell-teapot seen from above: its light and mesh, uniform and refined.

Usage:
    python benchmarks/plot_refined_mesh.py [--quality draft] [-o docs/refined_mesh.png]

Solves the scene twice with the same seed, with ``--no-adaptive`` (the preset's uniform
mesh) and with refinement where the light changes (``transport.adaptive``), and draws the
floor's irradiance (Gouraud-shaded vertex values, grey) under its triangle edges (red).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def floor_panel(ax, solution, title):
    import matplotlib.tri as mtri

    floor = next(o for o in solution.objects if o.name == "floor")
    x, z = floor.positions[:, 0], floor.positions[:, 2]
    light = floor.radiance.mean(axis=1) @ np.array([0.2126, 0.7152, 0.0722])
    triangulation = mtri.Triangulation(x, z, floor.faces)
    ax.tripcolor(triangulation, light, shading="gouraud", cmap="gray", vmin=0, vmax=np.percentile(light, 99))
    ax.triplot(triangulation, color="crimson", linewidth=0.25, alpha=0.6)
    ax.set_aspect("equal")
    ax.set_axis_off()
    vertices = sum(o.num_vertices for o in solution.objects)
    ax.set_title(f"{title}: floor {floor.num_vertices:,} vertices, scene {vertices:,}", fontsize=10)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quality", default="draft")
    parser.add_argument("-o", "--output", type=Path, default=Path("docs/refined_mesh.png"))
    args = parser.parse_args(argv)

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from radiosity.scene.loaders import load_scene
    from radiosity.transport.adaptive import AdaptiveOptions, solve_adaptive
    from radiosity.transport.solve import SolveOptions

    scene = load_scene("cornell-teapot")
    opts = SolveOptions(quality=args.quality, seed=1)
    uniform = solve_adaptive(scene, opts, AdaptiveOptions(enabled=False))
    refined = solve_adaptive(scene, opts, AdaptiveOptions(enabled=True))
    fig, axes = plt.subplots(1, 2, figsize=(11, 5.6))
    floor_panel(axes[0], uniform, f"uniform ({args.quality})")
    floor_panel(axes[1], refined, f"refined where the light changes ({args.quality})")
    fig.tight_layout()
    fig.savefig(args.output, dpi=100, bbox_inches="tight")
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
