"""Every kind of bad scene input, shared by the loader tests and the CLI tests.

``BAD_INPUTS[case] = (file text or name, regex the one-line error must match)``.
"""

import textwrap


def write(path, text):
    path.write_text(textwrap.dedent(text))
    return path


GOOD_MATERIAL = "[materials.m]\ndiffuse = 0.5\n"
BAD_INPUTS = {
    "missing scene": (None, "not found"),
    "unknown built-in scene": ("cornel", "not found; built-in scenes"),
    "unknown builtin mesh": (GOOD_MATERIAL + '[[objects]]\nname="a"\nbuiltin="dodecahedron"\nmaterial="m"\n', "unknown builtin mesh 'dodecahedron'"),
    "unknown cornell part": (GOOD_MATERIAL + '[[objects]]\nname="a"\nbuiltin="cornell:roof"\nmaterial="m"\n', "unknown Cornell box part 'roof'"),
    "unknown material": (GOOD_MATERIAL + '[[objects]]\nname="a"\nbuiltin="cube"\nmaterial="gold"\n', "unknown material 'gold'"),
    "malformed toml": (GOOD_MATERIAL + "[[objects]]\nname = \n", "malformed TOML.*line 4"),
    "kd + ks > 1": ("[materials.hot]\ndiffuse = 0.7\nspecular = 0.5\nexponent = 10\n[[objects]]\nname='a'\nbuiltin='cube'\nmaterial='hot'\n", "hot.*1.2"),
    "negative reflectance": ("[materials.neg]\ndiffuse = [0.5, -0.1, 0.5]\n[[objects]]\nname='a'\nbuiltin='cube'\nmaterial='neg'\n", "neg.*negative"),
    "unknown key": ("[materials.m]\ndifuse = 0.5\n[[objects]]\nname='a'\nbuiltin='cube'\nmaterial='m'\n", "unknown key 'difuse'"),
    "missing mesh file": (GOOD_MATERIAL + '[[objects]]\nname="a"\nmesh="nowhere.obj"\nmaterial="m"\n', "nowhere.obj.*not found"),
    "nan coordinates": (GOOD_MATERIAL + '[[objects]]\nname="a"\nmesh="nan.obj"\nmaterial="m"\n', "NaN or infinite"),
    "duplicate names": (GOOD_MATERIAL + '[[objects]]\nname="a"\nbuiltin="cube"\nmaterial="m"\n[[objects]]\nname="a"\nbuiltin="quad"\nmaterial="m"\n', "unique"),
    "no objects": (GOOD_MATERIAL, "no \\[\\[objects\\]\\]"),
    "zero scale": (GOOD_MATERIAL + '[[objects]]\nname="a"\nbuiltin="cube"\nmaterial="m"\nscale=0\n', "scale"),
    "bad vector": (GOOD_MATERIAL + '[[objects]]\nname="a"\nbuiltin="cube"\nmaterial="m"\ntranslate=[1,2]\n', "translate"),
    "unknown format": ("", "unknown scene format"),
    "slash in a name": (GOOD_MATERIAL + '[[objects]]\nname="a/b"\nbuiltin="cube"\nmaterial="m"\n', "may not contain '/'"),
}


def bad_input_path(case, tmp_path):
    """Write the bad input for ``case`` and return what to pass to load_scene."""
    text, _ = BAD_INPUTS[case]
    (tmp_path / "nan.obj").write_text("v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n")
    if case == "missing scene":
        return str(tmp_path / "absent.toml")
    if case == "unknown built-in scene":
        return text
    if case == "unknown format":
        path = tmp_path / "scene.yaml"
        path.write_text("objects: []\n")
        return str(path)
    return str(write(tmp_path / "scene.toml", text))


def tiny_solution(path, name="plate"):
    """Write a valid solution.npz of one diffuse 2 x 2-quad object (V = 9) at ``path``;
    enough for every check a command makes before it works on the data."""
    import numpy as np

    from radiosity.files.solution import ObjectSolution, Solution
    from radiosity.physics.directions import DIFFUSE_DIRECTIONS

    u, v = np.meshgrid(np.arange(3.0), np.arange(3.0))
    faces = [[3 * r + c, 3 * r + c + 1, 3 * r + c + 4] for r in range(2) for c in range(2)]
    faces += [[3 * r + c, 3 * r + c + 4, 3 * r + c + 3] for r in range(2) for c in range(2)]
    obj = ObjectSolution(
        name=name,
        positions=np.stack([u.ravel(), v.ravel(), np.zeros(9)], axis=1),
        normals=np.tile([0.0, 0.0, 1.0], (9, 1)),
        tangents=np.tile([1.0, 0.0, 0.0], (9, 1)),
        faces=np.array(faces),
        directions=DIFFUSE_DIRECTIONS,
        radiance=np.full((9, len(DIFFUSE_DIRECTIONS), 3), 0.5),
        material={"diffuse": [0.5] * 3, "specular": [0.0] * 3, "exponent": 0.0, "emission": [0.0] * 3},
    )
    Solution(objects=(obj,)).save(path)
    return path


def replace_member(path, member, data):
    """Rewrite the zip at ``path`` with ``member`` (e.g. "meta.npy") holding ``data``."""
    import zipfile

    with zipfile.ZipFile(path) as z:
        members = {n: z.read(n) for n in z.namelist()}
    members[member] = data
    with zipfile.ZipFile(path, "w") as z:
        for n, d in members.items():
            z.writestr(n, d)
    return path


def npy_bytes(shape, dtype, payload=b""):
    """An .npy file whose header claims ``shape`` of ``dtype`` followed by ``payload``."""
    import io

    import numpy as np

    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": np.dtype(dtype).str, "fortran_order": False, "shape": shape})
    return buf.getvalue() + payload
