"""Emitter parts per glossy object: where a scene has more parts than one object's
displays draw (``transport.highlights.MAX_RECEIVER_PARTS``), each glossy object names
the brightest for it (a solution of version 5), its grid still holds every part's
highlight in closed form, and a file of that version round-trips; with fewer parts
every object draws them all, as before (a version 4 file, no ``emitter_parts``)."""

import numpy as np
import pytest
from many_lights import PER_SIDE, solved, two_plates

from radiosity.files.solution import load_solution
from radiosity.physics.emitters import emitter_grid
from radiosity.transport.highlights import LEFT_OUT, MAX_RECEIVER_PARTS


@pytest.fixture(scope="module")
def solution(tmp_path_factory):
    return solved(two_plates(tmp_path_factory.mktemp("parts")))


def test_each_object_names_the_parts_brightest_for_it(solution):
    assert len(solution.emitters) == 2 * PER_SIDE > MAX_RECEIVER_PARTS
    assert solution.version == 5
    for side in ("left", "right"):
        o = solution.object(side)
        assert o.emitter_parts is not None and len(o.emitter_parts) == MAX_RECEIVER_PARTS
        assert list(o.emitter_parts) == sorted(o.emitter_parts) and o.visibility.shape == (o.num_vertices, 16)
        sources = [solution.emitters[i].source for i in o.emitter_parts]
        own = [s for s in sources if s.startswith(side)]
        assert len(own) == PER_SIDE, sources  # its own lamps, nearer and facing it more, all kept
        assert [p.source for p in solution.parts_of(side)] == sources


def test_the_grid_holds_the_parts_that_reach_it_and_the_file_subtracts_the_named(solution):
    """Nothing but the lights and two plates that see nothing of each other: the
    radiance is the lights' highlights in closed form, all but the dimmest, whose light
    adds up to under LEFT_OUT of the object's (a percent); what a display subtracts on
    the grid is its named parts' alone, the rest (the other side's dimmest) stays in the
    grid."""
    for side in ("left", "right"):
        o = solution.object(side)
        m = o.material
        every = emitter_grid(solution.emitters, o.positions, o.normals, o.tangents, o.directions, m["specular"],
                             m["exponent"], nodes=solution.emitter_nodes, source=side)
        radiance = o.radiance.astype(np.float64)
        assert (radiance <= every * (1 + 1e-5) + 1e-7).all()
        assert 1 - LEFT_OUT <= radiance.sum() / every.sum() <= 1 + 1e-6
        named = solution.highlights(side)
        rest = radiance - named
        assert rest.min() > -1e-6 and 0 < rest.sum() < 0.3 * radiance.sum()


def test_a_version_5_file_round_trips(solution, tmp_path):
    solution.save(tmp_path / "s.npz")
    again = load_solution(tmp_path / "s.npz")
    assert again.version == 5
    for side in ("left", "right"):
        a, b = solution.object(side), again.object(side)
        assert np.array_equal(a.emitter_parts, b.emitter_parts) and np.array_equal(a.visibility, b.visibility)
        assert np.array_equal(solution.highlights(side), again.highlights(side))


def test_with_few_parts_every_object_draws_them_all(tmp_path):
    s = solved(two_plates(tmp_path, per_side=3))
    assert len(s.emitters) == 6 and s.version == 4
    assert all(o.emitter_parts is None and o.visibility.shape[1] == 6 for o in s.objects)


def test_a_named_part_out_of_range_or_twice_is_refused(solution, tmp_path):
    import dataclasses

    o = solution.object("left")
    with pytest.raises(ValueError, match="names a part twice"):
        dataclasses.replace(o, emitter_parts=np.r_[o.emitter_parts[:-1], o.emitter_parts[0]])
    bad = dataclasses.replace(o, emitter_parts=np.r_[o.emitter_parts[:-1], 25])
    with pytest.raises(ValueError, match="name part 25; there are 24"):
        dataclasses.replace(solution, objects=(bad, solution.object("right")))
    # of 40 parts (more than the 31 an object may draw) an object must name its own
    alls = [dataclasses.replace(solution.object(n), emitter_parts=None,
                                visibility=np.ones((solution.object(n).num_vertices, 48), np.float32))
            for n in ("left", "right")]
    with pytest.raises(ValueError, match="names its own"):
        dataclasses.replace(solution, objects=tuple(alls), emitters=solution.emitters * 2)
    # of 24 every object may draw all (as a version 4 file)
    every = [dataclasses.replace(a, visibility=a.visibility[:, :24]) for a in alls]
    assert dataclasses.replace(solution, objects=tuple(every)).version == 4


def test_the_summary_says_each_object_draws_its_brightest(solution):
    from radiosity.cli import _highlight_lines

    [line] = _highlight_lines(solution)
    assert "highlights 24 emitter part(s) in closed form" in line
    assert "each glossy object draws the brightest for it per pixel (16 to 16), its grid holds those that reach it" in line
