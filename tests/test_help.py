"""Every ``--help`` against the code it describes: the built-in scenes and scene formats
a help text names are the ones the loader takes, all of them; the presets' numbers are
the table's; what a user reads is wrapped without cutting a name at its hyphen."""

import argparse
import re

import pytest

from display import demo
from display.cli import build_parser
from radiosity.files.sniff import MESH_SUFFIXES, SCENE_SUFFIXES
from radiosity.policies import presets
from radiosity.scene import builtins

SCENE_COMMANDS = ("scene-info", "solve", "truth")  # the commands whose argument may be a scene
LISTED = re.compile(r"built-in scenes? \(([^)]*)\)")  # "a built-in scene (cornell, cornell-teapot, plates)"
NAMED = re.compile(r"built-in scenes ([\w+-]+(?:(?:, | and )[\w+-]+)*)")  # "the built-in scenes a and b"


def commands():
    """{command: its parser}, and the top level's one-line help of each."""
    parser = build_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return parser, action.choices, {c.dest: c.help for c in action._choices_actions}


def help_texts(parser):
    """Every text of a parser's help before wrapping: description, epilog, each argument's help."""
    texts = [parser.description or "", parser.epilog or ""]
    return texts + [a.help for a in parser._actions if a.help and a.help is not argparse.SUPPRESS]


def scene_names(text):
    """The built-in scenes a help text names, in order (none: it names none)."""
    names = []
    for listed in LISTED.findall(text):
        names += [n.strip() for n in listed.split(",")]
    for named in NAMED.findall(text):
        names += [n for n in re.split(r", | and ", named) if n]
    return names


def every_text():
    parser, choices, one_line = commands()
    for text in help_texts(parser):
        yield "vlights", text
    for name, sub in choices.items():
        yield f"vlights {name}", one_line[name]
        for text in help_texts(sub):
            yield f"vlights {name}", text


def test_no_help_names_a_built_in_scene_that_does_not_exist():
    wrong = [f"{where}: {name!r}" for where, text in every_text() for name in scene_names(text)
             if name not in builtins.SCENES]
    assert not wrong, "help texts name built-in scenes that do not exist: " + "; ".join(wrong)


@pytest.mark.parametrize("command", SCENE_COMMANDS)
def test_a_scene_argument_lists_every_built_in_scene_and_format(command):
    _, choices, _ = commands()
    argument = next(a for a in choices[command]._actions if a.dest in ("scene", "input"))
    assert scene_names(argument.help) == list(builtins.SCENES)
    for suffix in SCENE_SUFFIXES + MESH_SUFFIXES:
        assert suffix in argument.help, f"vlights {command} --help does not name {suffix}"
    assert "Mitsuba XML" in argument.help and "0.4-0.6 and 2-3" in argument.help
    assert "OBJ/MTL" in argument.help and "glTF" in argument.help


def test_the_demo_names_the_scenes_it_runs():
    _, choices, one_line = commands()
    for text in (one_line["demo"], choices["demo"].description):
        assert scene_names(text) == list(demo.SCENES)


def test_the_check_sees_a_missing_or_unknown_scene():
    """The tests above can fail: a list with a scene left out or one made up."""
    assert scene_names("a built-in scene (cornell, plates)") != list(builtins.SCENES)
    assert scene_names("the built-in scenes cornell-teapot and kitchen: ...") == ["cornell-teapot", "kitchen"]
    assert "kitchen" not in builtins.SCENES


def test_preset_defaults_are_the_tables():
    _, choices, _ = commands()
    solve = {a.dest: a.help for a in choices["solve"]._actions}
    for quality in presets.QUALITIES:
        p = presets.preset(quality)
        assert f"{quality} {p.photons:,}" in solve["photons"]
        assert f"{quality} {p.gather_samples}" in solve["gather_samples"]
    fit = {a.dest: a.help for a in choices["fit"]._actions}["quality"]
    truth = {a.dest: a.help for a in choices["truth"]._actions}["quality"]
    for quality in presets.QUALITIES:
        p = presets.preset(quality)
        assert f"{quality} {p.probe_lights} lights beside a probe, {p.fit_lights} alone, {p.fit_iterations} iterations" in fit
        assert f"{quality} {p.truth_spp}" in truth


@pytest.mark.parametrize("command", [None, "scene-info", "solve", "fit", "render", "compare", "view", "demo", "truth",
                                     "export", "serve"])
def test_every_help_prints_and_keeps_names_whole(command, capsys):
    """``vlights [COMMAND] --help`` exits 0, and no line ends in a name cut at its hyphen
    (cornell-/teapot, probe+/lights, built-/in)."""
    from display.cli import main

    with pytest.raises(SystemExit) as info:
        main(([command] if command else []) + ["--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    cut = [line for line in out.splitlines() if re.search(r"\w-$", line)]
    assert not cut, f"lines ending in a cut word: {cut}"
    if command in SCENE_COMMANDS:
        for name in builtins.SCENES:
            assert name in out
