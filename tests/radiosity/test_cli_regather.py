"""``vlights solve --extra-gather F --gather-tolerance E``: the extra gather passes,
their summary line and their refusals."""

import numpy as np

from display.cli import main
from radiosity.files.solution import load_solution


def run(argv, capsys):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def test_extra_gather_passes_are_run_and_reported(tmp_path, capsys):
    out = tmp_path / "s.npz"
    base = ["solve", "cornell-teapot", "-o", str(out), "--photons", "20000", "--gather-samples", "16",
            "--light-samples", "4", "--max-edge", "200"]
    code, stdout, err = run(base + ["--extra-gather", "0.5", "--gather-tolerance", "0.001"], capsys)
    assert code == 0
    # the memory estimate is said before the work, on stderr (stdout is the summary)
    said = [line for line in err.splitlines() if line.startswith("solve: about ")]
    assert said and " at most of " in said[-1] and "vertices; the largest part: " in said[-1], err
    assert "solve: about" not in stdout
    stats = load_solution(out).stats
    teapot = stats["regather"]["teapot"]
    # the tolerance is out of reach, so the budget binds: half a pass per vertex
    assert 0 < teapot["extra_passes"] <= 0.5 * teapot_vertices(out) and teapot["tolerance"] > 0.001
    assert "  regather " in stdout and f"teapot {teapot['regathered']:,} vertices" in stdout
    assert stats["regather"]["tall_block"]["max_passes"] >= 2

    code, stdout, _ = run(base + ["--extra-gather", "0"], capsys)
    assert code == 0 and "regather" not in stdout
    assert all(r["extra_passes"] == 0 for r in load_solution(out).stats["regather"].values())


def teapot_vertices(path):
    return len(load_solution(path).object("teapot").positions)


def test_bad_extra_gather_flags_are_refused(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for flag, value in (("--extra-gather", "-1"), ("--gather-tolerance", "nan")):
        code, out, err = run(["solve", "cornell-teapot", flag, value], capsys)
        assert code == 2 and out == "" and err.count("\n") == 1 and flag in err, err
    assert list(tmp_path.iterdir()) == []


def test_bad_emitter_highlight_flags_are_refused(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for flag, value in (("--emitter-nodes", "0"), ("--emitter-nodes", "33"), ("--visibility-samples", "0"),
                        ("--visibility-samples", "99999")):
        code, out, err = run(["solve", "cornell-teapot", flag, value], capsys)
        assert code == 2 and out == "" and err.count("\n") == 1 and flag in err, err
    assert list(tmp_path.iterdir()) == []


def test_the_summary_counts_the_objects_of_a_large_scene_instead_of_naming_each(tmp_path):
    # 180 glossy balls on three grids, each regathered, 20 lamps in closed form: three
    # short lines, not three lines of 180 (or 20) names; a small scene still names them
    from types import SimpleNamespace

    from radiosity.cli import LISTED, format_summary

    def balls(n):
        return [SimpleNamespace(name=f"ball_{i}", grid_n=(8, 16, 48)[i % 3], is_diffuse=False, emitter_parts=None)
                for i in range(n)]

    def summary(n, lamps):
        times = {"setup": 0.1, "photons": 1.0, "density": 0.5, "gather": 2.0, "highlights": 0.5}
        stats = {"triangles": 10, "vertices": 10, "quality": "draft", "seed": 1, "threads": 2, "photons": 10,
                 "photon_rays": 10, "photon_rays_per_s": 1e6, "gather_rays": 10, "gather_rays_per_s": 1e6,
                 "time_s": times, "visibility_rays": 5,
                 "regather": {f"ball_{i}": {"regathered": 100 + i, "extra_passes": 162, "max_passes": 2 + i % 3,
                                            "tolerance": 0.1 + 0.001 * i} for i in range(n)}}
        parts = [SimpleNamespace(kind="polygon", points=np.zeros((4, 3)), source=f"lamp_{i}") for i in range(lamps)]
        (tmp_path / "s.npz").write_bytes(b"x")
        sol = SimpleNamespace(stats=stats, objects=balls(n), scene="interior", emitters=parts)
        return format_summary(sol, tmp_path / "s.npz").splitlines()

    lines = summary(180, 20)
    gather = next(line for line in lines if line.startswith("  gather"))
    assert "(grids: 180 glossy objects: 8x8 x 60, 16x16 x 60, 48x48 x 60)" in gather and "ball_" not in gather
    regather = next(line for line in lines if line.startswith("  regather"))
    assert regather == (f"  regather 180 objects, {sum(100 + i for i in range(180)):,} vertices +{162 * 180:,} passes "
                        "(at most 4, tolerance 0.1 to 0.279)")
    closed = next(line for line in lines if line.startswith("  highlights"))
    assert "from 20 objects (4-gon x 20)" in closed and "lamp_" not in closed
    small = "\n".join(summary(LISTED, 2))
    assert "ball_0 8x8" in small and "ball_0 100 vertices" in small and "lamp_1 (4-gon)" in small
