"""Mitsuba's BSDFs mapped onto the scene's materials: diffuse, twosided, the plastics
and conductors (a Phong lobe by ``radiosity.scene.microfacet``'s rule, the rough ones
keeping their own model), the dielectrics as glass, masks and what is approximated.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from radiosity.files.errors import InputError
from radiosity.physics.materials import MAX_ALPHA, MIN_ALPHA, Glass, Microfacet, fresnel_kd_limit
from radiosity.scene import microfacet

from .values import _Bitmap, _bitmap, _Props


@dataclass(frozen=True)
class _Surface:
    """A shape's material as the project models it, and what the shape needs."""

    diffuse: tuple = (0.5, 0.5, 0.5)
    specular: tuple = (0.0, 0.0, 0.0)
    exponent: float = 0.0
    twosided: bool = False
    visible: bool = True  # False: the shape is left out (a null bsdf, a dielectric)
    fresnel: tuple | None = None  # Schlick's F0 of a mapped plastic or conductor
    texture: _Bitmap | None = None  # multiplies diffuse at each point (``textures``)
    microfacet: Microfacet | None = None  # a rough plastic's or conductor's own model (the rest its Phong stand-in)
    glass: Glass | None = None  # a dielectric, thin dielectric or rough dielectric (no Phong part)
    opacity: _Bitmap | None = None  # a mask's opacity image (``textures.check_opacity``)

    def untextured(self):
        """This surface with its texture folded into the diffuse colour (its mean)."""
        if self.texture is None:
            return self
        diffuse = tuple(float(d * m) for d, m in zip(self.diffuse, self.texture.mean, strict=True))
        microfacet = self.microfacet
        if microfacet is not None and microfacet.kind == "roughplastic":
            microfacet = replace(microfacet, diffuse_reflectance=tuple(
                float(d * m) for d, m in zip(microfacet.diffuse_reflectance, self.texture.mean, strict=True)))
        return _Surface(diffuse, self.specular, self.exponent, self.twosided, self.visible, self.fresnel,
                        microfacet=microfacet)


def _bitmap_property(doc, props, name):
    """The ``_Bitmap`` of property ``name`` if it is a bitmap texture, else None."""
    item = props.named.get(name)
    if item is None or item[1].tag != "texture" or item[1].attrs.get("type") != "bitmap":
        return None
    return _bitmap(doc, item[1])


def _surface(doc, node):
    """The _Surface of a ``<bsdf>`` element (after ``<ref>``), made once per element:
    the shapes that refer to one bsdf share its surface and its texture (a plastic's
    rescaled image is made once, not once per shape)."""
    node = doc.deref(node, ("bsdf",))
    key = id(node)
    if key not in doc.surfaces:
        if key in doc.building:
            raise node.fail("refers to itself (a cycle of bsdfs through <ref>)")
        doc.building.add(key)
        try:
            doc.surfaces[key] = _make_surface(doc, node)
        finally:
            doc.building.discard(key)
    return doc.surfaces[key]


def _make_surface(doc, node):
    kind = node.attrs.get("type")
    props = _Props(doc, node)
    props.check_refs(("bsdf",))
    inner = [c for c in props.unnamed if c.tag == "bsdf"]
    if kind == "twosided":
        if not inner:
            raise node.fail("needs the <bsdf> it makes two-sided")
        if len(inner) > 1:
            node.warn("a different bsdf on each side: the front's is used on both")
        surface = _surface(doc, inner[0])
        if surface.glass is not None:  # glass has two faces already
            return surface
        return replace(surface, twosided=True)
    if kind == "diffuse":
        bitmap = _bitmap_property(doc, props, "reflectance")
        if bitmap is not None:
            return _Surface(diffuse=(1.0, 1.0, 1.0), texture=bitmap)
        return _Surface(diffuse=props.colour("reflectance", 0.5))
    if kind in ("plastic", "roughplastic", "conductor", "roughconductor"):
        return _microfacet_surface(node, props, kind)
    if kind == "null":
        return _Surface(diffuse=(0.0, 0.0, 0.0), visible=False)
    if kind in ("dielectric", "thindielectric", "roughdielectric"):
        return _glass_surface(node, props, kind)
    if kind in ("bumpmap", "normalmap"):
        if not inner:
            raise node.fail("needs the <bsdf> it perturbs")
        node.warn(f"the {kind}'s detail is not modelled: the bsdf beneath it is used as it is")
        return _surface(doc, inner[0])
    if kind == "mask":
        if not inner:
            raise node.fail("needs the <bsdf> it masks")
        bitmap = _bitmap_property(doc, props, "opacity")
        if bitmap is not None:
            surface = _surface(doc, inner[0])
            if surface.glass is not None or not surface.visible:
                node.warn("a mask over glass or a null bsdf: the mask is left out")
                return surface
            return replace(surface, opacity=bitmap)
        opacity = float(np.mean(props.colour("opacity", 0.5)))
        if opacity < 0.5:
            node.warn(f"mean opacity {opacity:.2f} < 0.5: the shape is left out")
            return _Surface(visible=False)
        node.warn(f"mean opacity {opacity:.2f} >= 0.5: the shape is taken as opaque")
        return _surface(doc, inner[0])
    if kind == "blendbsdf":
        if len(inner) != 2:
            raise node.fail("needs two <bsdf> to blend")
        weight = float(np.mean(props.colour("weight", 0.5)))
        if not 0.0 <= weight <= 1.0:
            raise node.fail(f"the blend's weight must be between 0 and 1, got {weight:g}")
        a, b = _surface(doc, inner[0]), _surface(doc, inner[1])
        if a.texture is not None or b.texture is not None:
            node.warn("a blend of textured bsdfs: each texture taken as its mean colour")
            a, b = a.untextured(), b.untextured()
        node.warn(f"blended as one Phong lobe: colours mixed with weight {weight:.2f}, the exponent of the "
                  "glossier part")
        mix = lambda u, v: tuple((1 - weight) * x + weight * y for x, y in zip(u, v, strict=True))  # noqa: E731
        glossier = a if a.exponent >= b.exponent else b
        diffuse, specular, exponent = mix(a.diffuse, b.diffuse), mix(a.specular, b.specular), glossier.exponent
        if glossier.fresnel is not None and any(specular):  # its Fresnel for the blend, kd within the energy bound
            diffuse = tuple(np.minimum(diffuse, fresnel_kd_limit(specular, glossier.fresnel, exponent)))
        return _Surface(diffuse, specular, exponent, a.twosided or b.twosided, a.visible or b.visible,
                        glossier.fresnel if any(specular) else None)
    colour = props.colour("base_color") or props.colour("reflectance") or props.colour("diffuse_reflectance")
    node.warn(f"bsdf type {kind!r} is not modelled: taken as diffuse"
              + (" with its base colour" if colour is not None else " 0.5"))
    return _Surface(diffuse=colour or (0.5, 0.5, 0.5))


def _roughness(node, props):
    """A rough bsdf's isotropic alpha (Mitsuba's default 0.1; alpha_u and alpha_v as their
    geometric mean, with a warning where they differ)."""
    alpha = props.float("alpha")
    if alpha is None and props.float("alpha_u") is not None:
        au, av = props.float("alpha_u"), props.float("alpha_v", props.float("alpha_u"))
        alpha = math.sqrt(au * av)
        if au != av:
            node.warn(f"anisotropic roughness ({au:g}, {av:g}) taken as isotropic {alpha:.4g}")
    return 0.1 if alpha is None else alpha


def _glass_surface(node, props, kind):
    """dielectric, thindielectric, roughdielectric: a ``Glass`` interface (Mitsuba's
    defaults: int_ior bk7, ext_ior air, a rough one's beckmann 0.1)."""
    eta = _ior(props, "int_ior", 1.5046) / _ior(props, "ext_ior", 1.000277)
    if eta == 1.0:
        node.warn("int_ior equals ext_ior: the interface bends and reflects nothing, so the shape is left out")
        return _Surface(visible=False)
    distribution, alpha = props.string("distribution", "beckmann"), 0.0
    if kind == "roughdielectric":
        alpha = _roughness(node, props)
        if distribution == "phong":
            node.warn("the phong distribution is mapped as beckmann of the same alpha")
            distribution = "beckmann"
        if not MIN_ALPHA <= alpha <= MAX_ALPHA:
            clipped = float(np.clip(alpha, MIN_ALPHA, MAX_ALPHA))
            node.warn(f"roughness alpha {alpha:g} taken as {clipped:g}, the nearest the microfacet model holds "
                      f"({MIN_ALPHA:g} to {MAX_ALPHA:g})")
            alpha = clipped
    elif distribution not in ("ggx", "beckmann"):
        distribution = "beckmann"
    for name in ("specular_reflectance", "specular_transmittance"):
        item = props.named.get(name)
        if item is not None and item[1].tag == "texture":
            node.warn(f"a textured {name} is taken as its mean colour")
    try:
        glass = Glass(kind, eta, distribution, alpha,
                      tuple(min(c, 1.0) for c in props.colour("specular_reflectance", 1.0)),
                      tuple(min(c, 1.0) for c in props.colour("specular_transmittance", 1.0)))
    except ValueError as exc:
        raise node.fail(str(exc)) from None
    return _Surface(diffuse=(0.0, 0.0, 0.0), glass=glass)


def _microfacet_surface(node, props, kind):
    """plastic, roughplastic, conductor, roughconductor by ``microfacet.phong_lobe_for``'s
    measured rule (the exponent that matches the lobe's half-maximum solid angle, ks
    and kd fitted to the original's albedos over incidence)."""
    alpha, distribution = None, props.string("distribution", "beckmann")
    if kind.startswith("rough"):
        alpha = _roughness(node, props)
        if distribution == "phong":  # Mitsuba 0.x's third distribution: close to Beckmann's at the same alpha
            node.warn("the phong distribution is mapped as beckmann of the same alpha")
            distribution = "beckmann"
    params = {"specular_reflectance": props.colour("specular_reflectance", 1.0)}
    bitmap = None
    if kind.endswith("plastic"):
        bitmap = _bitmap_property(props.doc, props, "diffuse_reflectance")
        params |= {"int_ior": _ior(props, "int_ior", 1.49), "ext_ior": _ior(props, "ext_ior", 1.000277),
                   "nonlinear": props.boolean("nonlinear")}
        if bitmap is None:
            params["diffuse_reflectance"] = props.colour("diffuse_reflectance", 0.5)
        else:
            brightest = np.clip(bitmap.texture.reshape(-1, 3).max(axis=0).astype(np.float64), 0.0, 1.0)
            params["diffuse_reflectance"] = tuple(np.where(brightest > 0, brightest, 1.0))
    elif "eta" in props.named or "k" in props.named:
        params |= {"eta": props.colour("eta", 0.0), "k": props.colour("k", 1.0)}
    else:
        params["material"] = props.string("material", "none")
    try:
        kd, ks, exponent, fresnel = microfacet.phong_lobe(kind, distribution, alpha if alpha is not None else 0.1,
                                                          **params)
        model = None
        if alpha is not None:  # the smooth kinds keep their Phong stand-in (n = MAX_EXPONENT) everywhere
            reference = microfacet.reference_brdf(kind, distribution, alpha, **params)
            if not MIN_ALPHA <= alpha <= MAX_ALPHA:
                node.warn(f"roughness alpha {alpha:g} taken as {float(np.clip(alpha, MIN_ALPHA, MAX_ALPHA)):g}, "
                          f"the nearest the microfacet model holds ({MIN_ALPHA:g} to {MAX_ALPHA:g})")
            model = Microfacet(kind, distribution, float(np.clip(alpha, MIN_ALPHA, MAX_ALPHA)),
                               (reference.eta,) * 3 if kind == "roughplastic" else tuple(reference.eta),
                               (0.0,) * 3 if kind == "roughplastic" else tuple(reference.k),
                               tuple(reference.specular_reflectance),
                               tuple(reference.diffuse_reflectance) if kind == "roughplastic" else (0.0,) * 3,
                               bool(getattr(reference, "nonlinear", False)))
    except (InputError, ValueError) as exc:
        raise node.fail(str(exc)) from None
    if bitmap is None:
        return _Surface(diffuse=kd, specular=ks, exponent=exponent, fresnel=fresnel, microfacet=model)
    return _Surface(diffuse=kd, specular=ks, exponent=exponent, fresnel=fresnel, microfacet=model,
                    texture=_plastic_texture(bitmap, kind, distribution, alpha, params))


def _plastic_texture(bitmap, kind, distribution, alpha, params):
    """A plastic's diffuse texture relative to its brightest texel M (the
    ``diffuse_reflectance`` its lobe was mapped with): g(texel) / g(M), g the
    substrate's kd' = kd / (1 - R_int) (linear: the texel over M) or, ``nonlinear``,
    kd / (1 - kd R_int) with the interface's internal reflectance R_int."""
    brightest = np.asarray(params["diffuse_reflectance"], dtype=np.float64)
    texels = bitmap.texture.astype(np.float64)
    if not params.get("nonlinear"):
        return bitmap.scaled(texels / brightest)
    linear = dict(params, diffuse_reflectance=1.0, nonlinear=False)
    r_int = 1.0 - 1.0 / float(microfacet.reference_brdf(kind, distribution, alpha or 0.1, **linear).substrate[0])
    g = lambda kd: kd / (1.0 - kd * r_int)  # noqa: E731
    return bitmap.scaled(np.clip(g(texels) / g(brightest), 0.0, 1.0))


_NAMED_IOR = {"vacuum": 1.0, "helium": 1.000036, "hydrogen": 1.000132, "air": 1.000277, "carbon dioxide": 1.00045,
              "water": 1.333, "acetone": 1.36, "ethanol": 1.361, "carbon tetrachloride": 1.461, "glycerol": 1.4729,
              "benzene": 1.501, "silicone oil": 1.52045, "bromine": 1.661, "water ice": 1.31, "fused quartz": 1.458,
              "pyrex": 1.47, "acrylic glass": 1.49, "polypropylene": 1.49, "bk7": 1.5046, "glass": 1.5046,
              "sodium chloride": 1.544, "amber": 1.55, "pet": 1.575, "polycarbonate": 1.58, "diamond": 2.419}


def _ior(props, name, default):
    text = props.string(name) if name in props.named and props.named[name][0].tag == "string" else None
    if text is not None:
        if text.lower() not in _NAMED_IOR:
            raise props.named[name][0].fail(f"unknown index of refraction {text!r} (known: {', '.join(_NAMED_IOR)})")
        return _NAMED_IOR[text.lower()]
    value = props.float(name, default)
    if not value > 0:
        raise props.node.fail(f"{name} must be > 0, got {value}")
    return value
