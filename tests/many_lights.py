"""A scene of more emitter parts than one object's displays draw (the tests of emitter
parts per object, in the solver, the fit and the displays): two glossy plates, each
under its own point lights."""

import textwrap

from radiosity.scene.loaders import load_scene
from radiosity.transport.solve import SolveOptions, solve

PER_SIDE = 12  # point lights over each plate: 24 in all, more than one object draws


def two_plates(tmp_path, per_side=PER_SIDE):
    """Two glossy plates (no diffuse part, side by side in one plane: neither sees the
    other) 2 apart, each under ``per_side`` point lights, nothing else: every light
    reaches both, its own plate's brightest."""
    lights = []
    for side, x in (("left", -1.0), ("right", 1.0)):
        for i in range(per_side):
            dx, dz = 0.15 * (i % 5) - 0.3, 0.2 * (i // 5) - 0.1
            lights.append(f'[[lights]]\nname = "{side}_{i}"\nkind = "point"\nposition = [{x + dx}, 1.0, {dz}]\n'
                          f"intensity = {1.0 + 0.1 * i}\n")
    text = textwrap.dedent("""
        [materials.metal]
        diffuse = 0.0
        specular = 0.6
        exponent = 30
        [[objects]]
        name = "left"
        builtin = "quad"
        material = "metal"
        scale = 1.5
        translate = [-1, 0, 0]
        [[objects]]
        name = "right"
        builtin = "quad"
        material = "metal"
        scale = 1.5
        translate = [1, 0, 0]
    """) + "".join(lights)
    path = tmp_path / "plates.toml"
    path.write_text(text)
    return load_scene(path)


def solved(scene):
    return solve(scene, SolveOptions(quality="draft", photons=20_000, threads=2, grid=8, extra_gather=0,
                                     max_edge=0.5))
