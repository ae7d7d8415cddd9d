"""Fixtures of the display tests: tiny solution and fit files, the draft Cornell box's
solution, a guard against making a GL context, and the command run in this process."""

import pytest
from display_fixtures import tiny_solution, write_pair


@pytest.fixture(scope="session")
def tiny_pair(tmp_path_factory):
    """(fit.npz, solution.npz) of the tiny scene, lit."""
    return write_pair(tmp_path_factory.mktemp("tiny"), tiny_solution())


@pytest.fixture(scope="session")
def black_pair(tmp_path_factory):
    """(fit.npz, solution.npz) of the tiny scene with no light: every radiance 0."""
    return write_pair(tmp_path_factory.mktemp("black"), tiny_solution(scale=0.0))


@pytest.fixture(scope="session")
def flat_pair(tmp_path_factory):
    """(fit.npz, solution.npz) of the wall alone, uniformly lit: the reference, the
    fitted and the diffuse pictures are identical (PSNR infinite)."""
    return write_pair(tmp_path_factory.mktemp("flat"), tiny_solution(glossy=False))


@pytest.fixture(scope="session")
def cornell_draft():
    """The Cornell box (diffuse, with a camera) solved at draft with seed 3: a real solve,
    made once for every module that needs one lit scene (tests must not change it)."""
    from radiosity.scene.loaders import load_scene
    from radiosity.transport.solve import SolveOptions, solve

    return solve(load_scene("cornell"), SolveOptions(quality="draft", seed=3))


@pytest.fixture
def no_gl(monkeypatch):
    """Make creating a GL context fail the test: a refusal must come before it."""
    import display.gl

    def refuse(*_args, **_kwargs):
        raise AssertionError("a GL context was made before the refusal")

    monkeypatch.setattr(display.gl, "headless_context", refuse)


@pytest.fixture
def cli(capsys):
    """Run ``vlights`` in this process: cli(*argv) -> (exit status, stdout, stderr)."""
    from display.cli import main

    def run(*argv):
        try:
            code = main([str(a) for a in argv])
        except SystemExit as exc:  # argparse exits by itself
            code = exc.code
        out, err = capsys.readouterr()
        return code, out, err

    return run
