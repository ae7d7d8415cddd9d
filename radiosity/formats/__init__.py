"""What the other stages may import from the radiosity stage: the file formats.

- errors: ``InputError`` (one line, exit status 2), ``SceneWarning``;
- atomic writes (``atomic_output``) and output-path checks (``check_output``);
- input files: ``inputs`` (regular files of a sane size, bounded nesting) and the one
  sniffer, ``input_kind`` / ``require_format`` (what a file is: solution, fit, scene, mesh);
- ``npz``: the one reader and writer of both file contracts, ``file_format``;
- the solution file: ``Solution``, ``ObjectSolution``, ``load_solution``;
- the equal-area direction grid of the solution's directions (``directions``);
- cameras: ``Camera``, ``camera_from_dict``, ``load_views``;
- the material record (``Material``) the solution's meta carries.

Nothing here imports the scene loaders or the light transport.
"""

from radiosity.formats.atomic import atomic_output, check_output
from radiosity.formats.camera import Camera, camera_from_dict, load_views
from radiosity.formats.errors import InputError, SceneWarning
from radiosity.formats.material import Material
from radiosity.formats.npz import file_format, open_archive, write_archive
from radiosity.formats.sniff import input_kind, require_format
from radiosity.formats.solution import ObjectSolution, Solution, load_solution

__all__ = [
    "Camera",
    "InputError",
    "Material",
    "ObjectSolution",
    "SceneWarning",
    "Solution",
    "atomic_output",
    "camera_from_dict",
    "check_output",
    "file_format",
    "input_kind",
    "load_solution",
    "load_views",
    "open_archive",
    "require_format",
    "write_archive",
]
