"""Time and peak memory of every stage against the scene's size.

The scene (``interior``, written as a TOML file): a closed hall divided into rooms by
full-height walls with a doorway between neighbours; every room is furnished alike: a
table (a cube), a chair (a cylinder closed by a disk), a diffuse statue (an icosphere of 5,120
triangles), a glossy ball on the table (Phong exponent 20, 100 or 1000, room by room)
and a lamp (an area light under the ceiling). The number of rooms sets the input
triangles, from about 1.7 x 10^4 (3 rooms) to 10^6 (180 rooms), and the mix of work is
the same at every size: glossy balls are about 6 % of the triangles, as the glossy
objects of a furnished interior. Every stage runs as the command a user types
(``vlights scene-info``, ``solve``, ``fit``, ``render``, ``export``) in a process of its
own, timed, its peak resident memory read from the kernel (``os.wait4``'s rusage),
after an untimed solve and fit of a small interior (numba's kernels compiled or loaded
first: no stage's time holds a compile).

    python benchmarks/bench_scale.py [--triangles 10000 100000] [--quality draft]

Writes benchmarks/results/scale.jsonl (scale_medium.jsonl, scale_high.jsonl at the other
qualities; scale_dask.jsonl for a run with the stages solve-dask or fit-dask, solve and fit
on a Dask LocalCluster of this machine, threads against Dask): one row per size and stage
(seconds, peak MB),
and the log-log slope of each stage's time and memory between consecutive sizes (the
target: <= 1.15 between 10^5 and 10^6); and the plot scale.png (scale_medium.png,
...): each stage's seconds and peak memory against triangles, log-log, slopes labelled, the
targets drawn (``--plot-only`` draws it again from the results file).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from _common import RESULTS, Recorder, run_vlights

ROOM = 4.0  # a room's side (scene units: metres)
HEIGHT = 3.0
DOOR = 1.0  # the doorway in each inner wall
THICK = 0.1  # the inner walls' thickness
EXPONENTS = (20, 100, 1000)  # the glossy balls' Phong exponents, room by room: plastic, varnish, polished metal
STATUE = 4  # the diffuse statue's icosphere subdivisions (5,120 triangles)
BALL = 2  # the glossy ball's (320 triangles)
PER_ROOM = 5_600  # input triangles of one room, about (statue, ball, chair, table, walls, lamp)

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
[materials.stone]
diffuse = [0.6, 0.55, 0.5]
[materials.lamp]
emission = 16.0
{glossy}
"""


def layout(triangles):
    """(rooms along x, rooms along z) for about ``triangles`` input triangles. Every room
    is furnished alike (PER_ROOM triangles, one glossy ball) and the balls' exponents
    cycle through EXPONENTS, so the rooms come in threes: the scene's mix of work is
    the same at every size (only its amount grows), from 3 rooms (about 1.7 x 10^4
    triangles) up."""
    rooms = max(3, 3 * round(triangles / PER_ROOM / 3))
    best = min(((a, rooms // a) for a in range(1, rooms + 1) if rooms % a == 0), key=lambda ab: abs(ab[0] - ab[1]))
    return best


def objects(nx, nz):
    """The TOML [[objects]] of ``nx`` x ``nz`` rooms: a closed hall, inner walls of full
    height with a doorway between neighbouring rooms, and in each room a table, a chair,
    a diffuse statue, a glossy ball on the table and a lamp under the ceiling."""
    out = []

    def add(name, builtin, material, **keys):
        lines = [f'[[objects]]\nname = "{name}"\nbuiltin = "{builtin}"\nmaterial = "{material}"']
        for key, value in keys.items():
            lines.append(f"{key} = {json.dumps(value)}")  # TOML's numbers, lists and booleans as JSON writes them
        out.append("\n".join(lines))

    sx, sz = nx * ROOM, nz * ROOM
    add("floor", "quad", "floor", scale=[sx, 1.0, sz], translate=[sx / 2, 0.0, sz / 2])
    add("ceiling", "quad", "wall", scale=[sx, 1.0, sz], flip=True, translate=[sx / 2, HEIGHT, sz / 2])
    half = HEIGHT / 2
    add("outer_north", "quad", "wall", scale=[sx, 1.0, HEIGHT], rotate_deg=[90, 0, 0], translate=[sx / 2, half, 0.0])
    add("outer_south", "quad", "wall", scale=[sx, 1.0, HEIGHT], rotate_deg=[-90, 0, 0], translate=[sx / 2, half, sz])
    add("outer_west", "quad", "wall", scale=[HEIGHT, 1.0, sz], rotate_deg=[0, 0, -90], translate=[0.0, half, sz / 2])
    add("outer_east", "quad", "wall", scale=[HEIGHT, 1.0, sz], rotate_deg=[0, 0, 90], translate=[sx, half, sz / 2])
    piece = (ROOM - DOOR) / 2  # each side of a doorway
    for i in range(nx):
        for j in range(nz):
            x0, z0 = i * ROOM, j * ROOM
            k = i * nz + j
            if j > 0:  # the wall to the room at lower z, a doorway in its middle
                for side, x in (("a", x0 + piece / 2), ("b", x0 + ROOM - piece / 2)):
                    add(f"wall_z{k}{side}", "cube", "wall", scale=[piece, HEIGHT, THICK], translate=[x, half, z0])
            if i > 0:  # the wall to the room at lower x
                for side, z in (("a", z0 + piece / 2), ("b", z0 + ROOM - piece / 2)):
                    add(f"wall_x{k}{side}", "cube", "wall", scale=[THICK, HEIGHT, piece], translate=[x0, half, z])
            add(f"table_{k}", "cube", "wood", scale=[1.2, 0.75, 0.8], translate=[x0 + 1.3, 0.375, z0 + 2.0])
            add(f"chair_{k}", "cylinder", "cloth", segments=24, scale=[0.25, 0.45, 0.25],
                rotate_deg=[-90, 0, 0], translate=[x0 + 2.5, 0.0, z0 + 2.7])
            # its seat closes it: an open cylinder is black inside in the truth and lit in the displays
            add(f"seat_{k}", "disk", "cloth", segments=24, scale=[0.25, 0.45, 1.0],
                rotate_deg=[-90, 0, 0], translate=[x0 + 2.5, 0.25, z0 + 2.7])
            add(f"statue_{k}", "sphere", "stone", subdivisions=STATUE, scale=0.4, translate=[x0 + 3.0, 0.4, z0 + 0.9])
            add(f"ball_{k}", "sphere", f"glossy_{k % len(EXPONENTS)}", subdivisions=BALL, scale=0.25,
                translate=[x0 + 1.3, 1.0, z0 + 2.0])
            add(f"lamp_{k}", "quad", "lamp", scale=[0.5, 1.0, 0.5], flip=True, translate=[x0 + 2.0, HEIGHT - 0.01, z0 + 2.0])
    return out


def write_scene(path, triangles):
    nx, nz = layout(triangles)
    glossy = "\n".join(f"[materials.glossy_{i}]\ndiffuse = 0.05\nspecular = 0.6\nexponent = {n}"
                       for i, n in enumerate(EXPONENTS))
    header = HEADER.format(cx=0.4, cz=0.4, lx=ROOM * 0.75, lz=ROOM * 0.75, glossy=glossy)
    path.write_text(header + "\n" + "\n\n".join(objects(nx, nz)) + "\n")
    return nx, nz


def run(args, cwd):
    """``_common.run_vlights`` of ``args`` in ``cwd``, which must succeed: (seconds, peak
    resident MB of the process, peak MB of its process tree)."""
    done = run_vlights(args, cwd)
    if done.exit_code != 0:
        raise SystemExit(f"vlights {' '.join(map(str, args))} failed: {done.last_line}")
    return done.seconds, done.peak_mb, done.tree_mb


STAGES = ("scene-info", "solve", "fit", "render", "export")
DASK_STAGES = ("solve-dask", "fit-dask")  # the same commands with --scheduler dask: a LocalCluster on this machine


def same_arrays(a, b):
    """Whether two .npz files hold the same arrays, bit for bit (``meta`` aside: times)."""
    import numpy as np

    with np.load(a) as x, np.load(b) as y:
        return x.files == y.files and all(np.array_equal(x[k], y[k]) for k in x.files if k != "meta")


def uncompressed(path):
    """Bytes of the arrays of an .npz as they are in memory (its members' sizes)."""
    import zipfile

    with zipfile.ZipFile(path) as z:
        return sum(i.file_size for i in z.infolist())


def warm_up(directory):
    """Solve and fit a small interior once, untimed: numba compiles (or loads from its
    cache) every kernel the stages use, so that no stage's time holds a compile."""
    write_scene(directory / "warm.toml", 10_000)
    for args in (["solve", "warm.toml", "--quality", "draft", "--photons", "100000", "-o", "warm.npz"],
                 ["fit", "warm.npz", "--workers", "1", "-o", "warm_fit.npz"]):
        run(args, directory)


def plot(rows, path):
    """Per stage, seconds and the process tree's peak memory against input triangles,
    log-log, each segment labelled with its slope; the targets drawn: 5 minutes for
    solve + fit, 8 GB, the fit's 2 x the solution's arrays."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    runs = [r for r in rows if "seconds" in r]
    stages = list(dict.fromkeys(r["stage"] for r in runs))
    fig, (left, right) = plt.subplots(1, 2, figsize=(12, 4.6))
    for stage in stages:
        sel = sorted((r for r in runs if r["stage"] == stage), key=lambda r: r["triangles"])
        x = [r["triangles"] for r in sel]
        for ax, key in ((left, "seconds"), (right, "tree_peak_mb")):
            y = [r[key] for r in sel]
            line, = ax.plot(x, y, "o-", label=stage)
            for (x0, y0), (x1, y1) in zip(zip(x, y), zip(x[1:], y[1:])):
                slope = math.log(y1 / y0) / math.log(x1 / x0)
                ax.annotate(f"{slope:.2f}", (math.sqrt(x0 * x1), math.sqrt(y0 * y1)), fontsize=7,
                            color=line.get_color(), ha="center", va="bottom")
    both = {}
    for r in runs:
        if r["stage"] in ("solve", "fit"):
            both.setdefault(r["triangles"], []).append(r["seconds"])
    pairs = sorted((t, sum(v)) for t, v in both.items() if len(v) == 2)
    if pairs:
        left.plot(*zip(*pairs), "k--", lw=1, label="solve + fit")
    left.axhline(300, color="grey", lw=0.8, ls=":")
    left.text(runs[0]["triangles"], 300, "5 min (solve + fit, 10^6)", fontsize=7, va="bottom", color="grey")
    right.axhline(8192, color="grey", lw=0.8, ls=":")
    right.text(runs[0]["triangles"], 8192, "8 GB", fontsize=7, va="bottom", color="grey")
    fits = sorted((r["triangles"], 2 * r["solution_mb"]) for r in runs if r["stage"] == "fit" and "solution_mb" in r)
    if fits:
        right.plot(*zip(*fits), color="grey", lw=0.8, ls="--", label="2 x solution (fit's target)")
    for ax, label in ((left, "seconds"), (right, "peak MB (process tree)")):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("input triangles")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
    left.legend(fontsize=7)
    right.legend(fontsize=7)
    fig.suptitle(f"bench_scale, {runs[0].get('quality', 'draft')}, {runs[0].get('cores')} cores: "
                 "each stage against triangles (labels: log-log slopes)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--triangles", type=int, nargs="+", default=[10_000, 100_000])
    parser.add_argument("--quality", default="draft", choices=("draft", "medium", "high"))
    parser.add_argument("--keep", type=Path, help="keep the scenes and outputs in this directory")
    parser.add_argument("--stages", nargs="+", default=list(STAGES), choices=STAGES + DASK_STAGES,
                        help="the stages to run (the others' outputs must be in --keep from an earlier run); "
                        "solve-dask and fit-dask run solve and fit on a Dask LocalCluster (threads against Dask on "
                        "the same machine) and record whether their output has the same bits")
    parser.add_argument("--plot-only", action="store_true",
                        help="draw the plot again from the results file of --quality, running nothing")
    args = parser.parse_args(argv)
    name = "scale" if args.quality == "draft" else f"scale_{args.quality}"
    if args.plot_only:
        plot([json.loads(line) for line in (RESULTS / f"{name}.jsonl").read_text().splitlines() if line.strip()],
             RESULTS / f"{name}.png")
        return
    record = Recorder(benchmark="scale", quality=args.quality)
    stages = [s for s in STAGES + DASK_STAGES if s in args.stages]
    rows = {}
    with tempfile.TemporaryDirectory() as tmp:
        directory = args.keep or Path(tmp)
        directory.mkdir(parents=True, exist_ok=True)
        warm_up(Path(tmp))
        for target in args.triangles:
            d = directory / f"t{target}"
            d.mkdir(exist_ok=True)
            nx, nz = write_scene(d / "interior.toml", target)
            commands = {
                "scene-info": ["scene-info", "interior.toml", "--json"],
                "solve": ["solve", "interior.toml", "--quality", args.quality, "-o", "solution.npz"],
                "fit": ["fit", "solution.npz", "--quality", args.quality, "-o", "fit.npz"],
                "render": ["render", "fit.npz", "--size", "640x360", "-o", "render.png"],
                "export": ["export", "fit.npz", "-o", "web"],
                "solve-dask": ["solve", "interior.toml", "--quality", args.quality, "--scheduler", "dask",
                               "-o", "solution_dask.npz"],
                "fit-dask": ["fit", "solution.npz", "--quality", args.quality, "--scheduler", "dask",
                             "-o", "fit_dask.npz"],
            }
            twins = {"solve-dask": ("solution.npz", "solution_dask.npz"), "fit-dask": ("fit.npz", "fit_dask.npz")}
            info = subprocess.run([sys.executable, "-m", "display", "scene-info", "interior.toml", "--json"], cwd=d,
                                  capture_output=True, text=True, check=True,
                                  env=os.environ | {"PYTHONPATH": str(Path(__file__).resolve().parents[1])})
            triangles = json.loads(info.stdout)["totals"]["triangles"]
            for stage in stages:
                seconds, peak, tree = run(commands[stage], d)
                row = {"target": target, "triangles": triangles, "rooms": nx * nz, "stage": stage,
                       "seconds": round(seconds, 2), "peak_mb": round(peak, 1), "tree_peak_mb": round(tree, 1)}
                if stage in ("solve", "fit"):  # the fit's target: its peak <= 2 x the solution's arrays
                    row["solution_mb"] = round(uncompressed(d / "solution.npz") / 2**20, 1)
                if stage in twins and (d / twins[stage][0]).exists():
                    row["same_bits_as_threads"] = same_arrays(d / twins[stage][0], d / twins[stage][1])
                rows[(target, stage)] = record(row)
    targets = list(args.triangles)
    for a, b in zip(targets, targets[1:]):
        for stage in stages:
            ra, rb = rows[(a, stage)], rows[(b, stage)]
            ratio = math.log(rb["triangles"] / ra["triangles"])
            record({"stage": stage, "from": ra["triangles"], "to": rb["triangles"],
                    "time_slope": round(math.log(rb["seconds"] / ra["seconds"]) / ratio, 3),
                    "memory_slope": round(math.log(rb["tree_peak_mb"] / ra["tree_peak_mb"]) / ratio, 3)})
    if any(s in DASK_STAGES for s in stages):  # threads against Dask: a file of its own, the other left as it is
        record.save("scale_dask.jsonl")
    else:
        record.save(f"{name}.jsonl")
        plot(record.rows, RESULTS / f"{name}.png")


if __name__ == "__main__":
    main()
