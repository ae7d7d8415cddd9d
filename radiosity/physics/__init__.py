"""The physics every stage computes the same way: ``materials`` (the material record
and its albedo quadratures), ``emitters`` (emitter parts and their highlights in closed
form), ``ltc`` (a microfacet lobe's highlights, linearly transformed cosines),
``directions`` (the equal-area direction grid), ``environment`` (light from outside the
scene, its lookup and sampling), ``textures`` (diffuse textures, their lookup), ``cdf``
(drawing from a tabulated distribution). Each holds its numpy reference and, where the
solver needs one, its numba kernel beside it.

Part of the radiosity stage's shared core, with ``radiosity.files`` and
``radiosity.policies``: what the other stages may import (the README's stage rule).
Nothing here imports the scene loaders or the light transport. Import each name from
its module; this package's own import loads nothing.
"""
