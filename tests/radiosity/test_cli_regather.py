"""``vlights solve --extra-gather F --gather-tolerance E``: the extra gather passes,
their summary line and their refusals."""

from display.cli import main
from radiosity.formats.solution import load_solution


def run(argv, capsys):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def test_extra_gather_passes_are_run_and_reported(tmp_path, capsys):
    out = tmp_path / "s.npz"
    base = ["solve", "cornell-teapot", "-o", str(out), "--photons", "20000", "--gather-samples", "16",
            "--light-samples", "4", "--max-edge", "200"]
    code, stdout, _ = run(base + ["--extra-gather", "0.5", "--gather-tolerance", "0.001"], capsys)
    assert code == 0
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
