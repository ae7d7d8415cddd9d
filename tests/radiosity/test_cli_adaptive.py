"""``vlights solve`` and ``scene-info`` with the refinement driven by the light:
--adaptive/--no-adaptive, --vertex-budget, vertices before and after in the reports."""

import json

from display.cli import main


def run(argv, capsys):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def test_scene_info_reports_the_budget(capsys):
    code, out, _ = run(["scene-info", "cornell", "--json"], capsys)
    assert code == 0
    info = json.loads(out)
    adaptive = info["adaptive"]
    assert adaptive["enabled"] and adaptive["vertices_before"] == info["totals"]["refined_vertices"]
    assert adaptive["vertex_budget"] == round(1.5 * adaptive["vertices_before"])
    code, out, _ = run(["scene-info", "cornell", "--vertex-budget", "5000"], capsys)
    assert code == 0 and "up to 5,000" in out
    code, out, _ = run(["scene-info", "cornell", "--no-adaptive"], capsys)
    assert code == 0 and "adaptive  off" in out


def test_solve_refines_within_the_budget_and_says_so(tmp_path, capsys):
    from radiosity.files.solution import load_solution

    out = tmp_path / "s.npz"
    code, stdout, _ = run(["solve", "cornell", "-o", str(out), "--photons", "40000", "--vertex-budget", "5000"], capsys)
    assert code == 0
    solution = load_solution(out)
    refinement = solution.stats["adaptive"]
    assert refinement["vertices_before"] < refinement["vertices_after"] == solution.stats["vertices"] <= 5000
    assert f"{refinement['vertices_before']:,} -> {refinement['vertices_after']:,} vertices" in stdout

    code, stdout, _ = run(["solve", "cornell", "-o", str(out), "--photons", "20000", "--no-adaptive"], capsys)
    assert code == 0 and "mesh     uniform" in stdout
    assert load_solution(out).stats["vertices"] == refinement["vertices_before"]


def test_an_explicit_max_edge_is_a_uniform_mesh_unless_adaptive_is_asked(tmp_path, capsys):
    from radiosity.files.solution import load_solution

    out = tmp_path / "s.npz"
    argv = ["solve", "cornell", "-o", str(out), "--photons", "20000", "--max-edge", "150"]
    assert run(argv, capsys)[0] == 0
    uniform = load_solution(out).stats
    assert not uniform["adaptive"]["enabled"]
    assert run(argv + ["--adaptive"], capsys)[0] == 0
    refined = load_solution(out).stats
    assert refined["adaptive"]["enabled"] and refined["vertices"] >= uniform["vertices"]


def test_a_bad_budget_is_refused(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = run(["solve", "cornell", "--vertex-budget", "0"], capsys)
    assert code == 2 and out == "" and err.count("\n") == 1 and "--vertex-budget" in err
    assert list(tmp_path.iterdir()) == []
