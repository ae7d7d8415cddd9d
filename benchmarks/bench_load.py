"""How long a Mitsuba XML scene takes to load, against its triangles (the target:
100,000 triangles in under 10 s on 2 cores).

The scene is generated: a room of rectangles and a grid of meshes (icospheres and
tori), a third each as OBJ, PLY and Mitsuba's serialized format, plus tessellated
spheres and cylinders, every shape with a transform and a bsdf (diffuse, roughplastic,
roughconductor; some twosided). Timed: ``load_scene`` (parse, read the meshes,
transform, weld, normals), median of --repeats runs in a fresh process each.

    python benchmarks/bench_load.py                   # about 1.5 x 10^4, 10^5 and 2.5 x 10^5 triangles
    python benchmarks/bench_load.py --triangles 100000 --repeats 5
"""

from __future__ import annotations

import argparse
import statistics
import struct
import subprocess
import sys
import tempfile
import zlib
from pathlib import Path

import numpy as np
import trimesh

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import Recorder  # noqa: E402

TIMER = """
import sys, time
start = time.perf_counter()
from radiosity.scene.loaders import load_scene
imported = time.perf_counter()
scene = load_scene(sys.argv[1])
done = time.perf_counter()
print(imported - start, done - imported, sum(o.n_triangles for o in scene.objects), len(scene.objects))
"""


def serialized(positions, faces):
    """Mitsuba's serialized format, version 4, one shape (see mitsuba.read_serialized)."""
    body = struct.pack("<I", 0) + b"mesh\0" + struct.pack("<QQ", len(positions), len(faces))
    body += positions.astype(np.float32).tobytes() + faces.astype(np.uint32).tobytes()
    shape = struct.pack("<HH", 0x041C, 4) + zlib.compress(body)
    return shape + struct.pack("<Q", 0) + struct.pack("<I", 1)


def make_scene(directory, triangles):
    """An XML scene of about ``triangles`` triangles in ``directory``; its path."""
    directory.mkdir(parents=True, exist_ok=True)
    bsdfs = ['<bsdf type="diffuse"><rgb name="reflectance" value="0.6, 0.5, 0.4"/></bsdf>',
             '<bsdf type="roughplastic"><float name="alpha" value="0.2"/></bsdf>',
             '<bsdf type="roughconductor"><float name="alpha" value="0.1"/><string name="material" value="none"/>'
             '</bsdf>']
    parts = ['<scene version="3.0.0">', '<sensor type="perspective"><float name="fov" value="60"/>'
             '<transform name="to_world"><lookat origin="0, 5, 30" target="0, 2, 0"/></transform></sensor>']
    for i, (axis, angle, offset) in enumerate([("x", -90, "0, 0, 0"), ("x", 0, "0, 10, -20")]):
        parts.append(f'<shape type="rectangle"><transform name="to_world"><scale value="20"/>'
                     f'<rotate {axis}="1" angle="{angle}"/><translate value="{offset}"/></transform>'
                     f'<bsdf type="twosided">{bsdfs[0]}</bsdf></shape>')
    parts.append('<shape type="rectangle"><transform name="to_world"><scale value="2"/><rotate x="1" angle="90"/>'
                 '<translate y="19"/></transform><emitter type="area"><rgb name="radiance" value="20"/></emitter>'
                 '</shape>')
    sphere = trimesh.creation.icosphere(subdivisions=4)  # 5,120 triangles
    per = len(sphere.faces)
    count = max(1, -(-triangles // per) + 1)
    side = int(np.ceil(np.sqrt(count)))
    for i in range(count):
        x, z = (i % side - side / 2) * 2.5, (i // side - side / 2) * 2.5
        kind = ("obj", "ply", "serialized", "sphere")[i % 4]
        transform = f'<transform name="to_world"><rotate y="1" angle="{i * 7}"/><translate value="{x}, 1, {z}"/>' \
                    '</transform>'
        if kind == "sphere":
            parts.append(f'<shape type="sphere">{transform}{bsdfs[i % 3]}</shape>')
            continue
        name = f"m{i}.{kind}"
        if kind == "serialized":
            (directory / name).write_bytes(serialized(np.asarray(sphere.vertices), np.asarray(sphere.faces)))
        else:
            sphere.export(directory / name)
        parts.append(f'<shape type="{kind}"><string name="filename" value="{name}"/>{transform}{bsdfs[i % 3]}'
                     '</shape>')
    parts.append("</scene>")
    path = directory / "scene.xml"
    path.write_text("\n".join(parts))
    return path


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--triangles", type=int, nargs="+", default=[10_000, 120_000, 300_000])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    record = Recorder(benchmark="load")
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.triangles:
            path = make_scene(Path(tmp) / f"n{n}", n)
            runs = []
            for _ in range(args.repeats):
                out = subprocess.run([sys.executable, "-c", TIMER, str(path)], capture_output=True, text=True,
                                     check=True).stdout.split()
                runs.append((float(out[0]), float(out[1]), int(out[2]), int(out[3])))
            record({"format": "mitsuba xml", "triangles": runs[0][2], "objects": runs[0][3],
                    "load_s_median": statistics.median(r[1] for r in runs),
                    "import_s_median": statistics.median(r[0] for r in runs), "repeats": args.repeats,
                    "target_s": 10.0 if runs[0][2] >= 100_000 else None})
    record.save("load.jsonl")
    return 0


if __name__ == "__main__":
    sys.exit(main())
