"""The words the display's flags take, light to import: the commands build their parsers
from here without loading the renderer, OpenGL's helpers or the fitter."""

from __future__ import annotations

__all__ = ["APPROACHES", "ASPECT", "DEMO_SCENES", "MODE_NAMES", "MODE_WORDS", "ORBIT_DEGREES", "SHADINGS"]

MODE_WORDS = {"fitted": "fitted", "reference": "solution", "diffuse": "diffuse"}  # a display's mode -> its word
MODE_NAMES = {word: mode for mode, word in MODE_WORDS.items()} | {"reference": "reference"}  # the older word read too
SHADINGS = ("gouraud", "pixel")
APPROACHES = ("blend", "probe", "none")  # glass and mirrors: how a display draws them (``display.glass``)
ORBIT_DEGREES = 35.0  # figure 5's views 2 and 3: view 1 turned this much each way
DEMO_SCENES = ("cornell-teapot", "plates")  # the demo's built-in scenes
ASPECT = {"plates": 9 / 16}  # height over width of a demo scene's figures (the plates are wide)
