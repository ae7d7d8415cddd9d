"""Time and peak memory of every stage against the scene's size (issue 25).

The scene (``interior``, written as a TOML file): a closed hall divided into rooms
by half-height walls, each room with a table (a cube), a chair (a cylinder), a ball (an
icosphere; every other one glossy, three Phong exponents) and a lamp (an area light
under the ceiling); the balls' subdivision and the number of rooms set the input
triangles, from about 10^4 to 10^6. Every stage runs as the command a user types
(``vlights scene-info``, ``solve``, ``fit``, ``render``, ``export``) in a process of its
own, timed, its peak resident memory read from the kernel (``os.wait4``'s rusage).

    python benchmarks/bench_scale.py [--triangles 10000 100000] [--quality draft]

Writes benchmarks/results/scale.jsonl: one row per size and stage (seconds, peak MB),
and the log-log slope of each stage's time and memory between consecutive sizes (the
issue's target: <= 1.15 between 10^5 and 10^6).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _common import Recorder

ROOM = 4.0  # a room's side (scene units: metres)
HEIGHT = 3.0
EXPONENTS = (50, 400, 3000)  # the glossy balls' Phong exponents, in turn

HEADER = """\
[camera]
position = [{cx}, 1.7, {cz}]
look_at = [{lx}, 0.8, {lz}]
up = [0, 1, 0]
fov_y_deg = 60

[materials.floor]
diffuse = [0.55, 0.5, 0.45]
[materials.wall]
diffuse = 0.7
[materials.wood]
diffuse = [0.45, 0.3, 0.18]
[materials.cloth]
diffuse = [0.2, 0.3, 0.55]
[materials.matte]
diffuse = [0.6, 0.2, 0.2]
[materials.lamp]
emission = 8.0
{glossy}
"""


def layout(triangles):
    """(rooms per side, ball subdivision) for about ``triangles`` input triangles: 2 x 2
    rooms up to 10^4, 4 x 4 up to 10^5, then 8 x 8 (a scene of hundreds of objects,
    not thousands); a ball of subdivision s has 20 * 4^s triangles, the rest of a room
    about 300, and s is the one that comes closest."""
    side = 2 if triangles <= 20_000 else 4 if triangles <= 200_000 else 8
    per_room = max(triangles / (side * side) - 300, 20)
    subdivisions = min(range(1, 9), key=lambda s: abs(math.log(20 * 4**s / per_room)))
    return side, subdivisions


def objects(side, subdivisions):
    """The TOML [[objects]] of ``side`` x ``side`` rooms."""
    out = []

    def add(name, builtin, material, **keys):
        lines = [f'[[objects]]\nname = "{name}"\nbuiltin = "{builtin}"\nmaterial = "{material}"']
        for key, value in keys.items():
            lines.append(f"{key} = {json.dumps(value)}")  # TOML's numbers, lists and booleans as JSON writes them
        out.append("\n".join(lines))

    size = side * ROOM
    add("floor", "quad", "floor", scale=[size, 1.0, size], translate=[size / 2, 0.0, size / 2])
    add("ceiling", "quad", "wall", scale=[size, 1.0, size], flip=True, translate=[size / 2, HEIGHT, size / 2])
    half = HEIGHT / 2
    add("outer_north", "quad", "wall", scale=[size, 1.0, HEIGHT], rotate_deg=[90, 0, 0], translate=[size / 2, half, 0.0])
    add("outer_south", "quad", "wall", scale=[size, 1.0, HEIGHT], rotate_deg=[-90, 0, 0], translate=[size / 2, half, size])
    add("outer_west", "quad", "wall", scale=[HEIGHT, 1.0, size], rotate_deg=[0, 0, -90], translate=[0.0, half, size / 2])
    add("outer_east", "quad", "wall", scale=[HEIGHT, 1.0, size], rotate_deg=[0, 0, 90], translate=[size, half, size / 2])
    for i in range(side):
        for j in range(side):
            x0, z0 = i * ROOM, j * ROOM
            k = i * side + j
            add(f"wall_{k}", "cube", "wall", scale=[ROOM * 0.6, 1.5, 0.1], translate=[x0 + ROOM * 0.3, 0.75, z0])
            add(f"table_{k}", "cube", "wood", scale=[1.2, 0.75, 0.8], translate=[x0 + 1.2, 0.375, z0 + 2.0])
            add(f"chair_{k}", "cylinder", "cloth", segments=24, scale=[0.25, 0.45, 0.25],
                rotate_deg=[-90, 0, 0], translate=[x0 + 2.4, 0.0, z0 + 2.6])
            glossy = k % 2 == 0
            material = f"glossy_{(k // 2) % len(EXPONENTS)}" if glossy else "matte"
            add(f"ball_{k}", "sphere", material, subdivisions=subdivisions, scale=0.3,
                translate=[x0 + 1.2, 1.05, z0 + 2.0])
            add(f"lamp_{k}", "quad", "lamp", scale=[0.5, 1.0, 0.5], flip=True, translate=[x0 + 2.0, HEIGHT - 0.01, z0 + 2.0])
    return out


def write_scene(path, triangles):
    side, subdivisions = layout(triangles)
    glossy = "\n".join(f"[materials.glossy_{i}]\ndiffuse = 0.05\nspecular = 0.6\nexponent = {n}"
                       for i, n in enumerate(EXPONENTS))
    size = side * ROOM
    header = HEADER.format(cx=0.3, cz=0.3, lx=size / 2, lz=size / 2, glossy=glossy)
    path.write_text(header + "\n" + "\n\n".join(objects(side, subdivisions)) + "\n")
    return side, subdivisions


def run(args, cwd):
    """Run ``vlights ARGS`` in a process of its own: (seconds, peak resident MB)."""
    env = os.environ | {"PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    start = time.perf_counter()
    process = subprocess.Popen([sys.executable, "-m", "display", *map(str, args)], cwd=cwd, env=env,
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(process.pid, 0)
    seconds = time.perf_counter() - start
    stderr = process.stderr.read().decode(errors="replace")
    process.stderr.close()
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"vlights {' '.join(map(str, args))} failed: {stderr.strip().splitlines()[-1:]}")
    return seconds, usage.ru_maxrss / 1024.0


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--triangles", type=int, nargs="+", default=[10_000, 100_000])
    parser.add_argument("--quality", default="draft", choices=("draft", "medium", "high"))
    parser.add_argument("--keep", type=Path, help="keep the scenes and outputs in this directory")
    args = parser.parse_args(argv)
    record = Recorder(benchmark="scale", quality=args.quality)
    stages = ("scene-info", "solve", "fit", "render", "export")
    rows = {}
    with tempfile.TemporaryDirectory() as tmp:
        directory = args.keep or Path(tmp)
        directory.mkdir(parents=True, exist_ok=True)
        for target in args.triangles:
            d = directory / f"t{target}"
            d.mkdir(exist_ok=True)
            side, subdivisions = write_scene(d / "interior.toml", target)
            commands = {
                "scene-info": ["scene-info", "interior.toml", "--json"],
                "solve": ["solve", "interior.toml", "--quality", args.quality, "-o", "solution.npz"],
                "fit": ["fit", "solution.npz", "--quality", args.quality, "-o", "fit.npz"],
                "render": ["render", "fit.npz", "--size", "640x360", "-o", "render.png"],
                "export": ["export", "fit.npz", "-o", "web"],
            }
            info = subprocess.run([sys.executable, "-m", "display", "scene-info", "interior.toml", "--json"], cwd=d,
                                  capture_output=True, text=True, check=True,
                                  env=os.environ | {"PYTHONPATH": str(Path(__file__).resolve().parents[1])})
            triangles = json.loads(info.stdout)["totals"]["triangles"]
            for stage in stages:
                seconds, peak = run(commands[stage], d)
                rows[(target, stage)] = record({"target": target, "triangles": triangles, "rooms": side * side,
                                                "ball_subdivisions": subdivisions, "stage": stage,
                                                "seconds": round(seconds, 2), "peak_mb": round(peak, 1)})
    targets = list(args.triangles)
    for a, b in zip(targets, targets[1:]):
        for stage in stages:
            ra, rb = rows[(a, stage)], rows[(b, stage)]
            ratio = math.log(rb["triangles"] / ra["triangles"])
            record({"stage": stage, "from": ra["triangles"], "to": rb["triangles"],
                    "time_slope": round(math.log(rb["seconds"] / ra["seconds"]) / ratio, 3),
                    "memory_slope": round(math.log(rb["peak_mb"] / ra["peak_mb"]) / ratio, 3)})
    record.save("scale.jsonl")


if __name__ == "__main__":
    main()
