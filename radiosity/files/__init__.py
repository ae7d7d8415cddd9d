"""The file contracts (docs/formats.md) and the safe reading and writing of every file:
``solution`` (solution.npz), ``npz`` (the one reader and writer of both archives),
``camera`` (the one camera type and views files), ``sniff`` (what an input file is),
``images`` (the one image reader), ``inputs`` (regular files of a sane size, bounded
nesting), ``atomic`` (whole files or none), ``errors`` (``InputError``, ``SceneWarning``).

Part of the radiosity stage's shared core, with ``radiosity.physics`` and
``radiosity.policies``: what the other stages may import (the README's stage rule).
Nothing here imports the scene loaders or the light transport. Import each name from
its module; this package's own import loads nothing.
"""
