"""Columns of the packed material table (``radiosity.scene.material_kernels.pack_materials``),
one row per material, read by every numba kernel that shades a surface.

The first columns hold the modified-Phong model (``KD`` .. ``HAS_FRESNEL``); every
material has them: a microfacet material keeps its Phong stand-in there for the stages
that draw Phong (the emitters' closed-form highlights, the fit, the displays). ``KIND``
says which model the transport kernels evaluate (``KIND_PHONG``, ``KIND_ROUGH_PLASTIC``,
``KIND_ROUGH_CONDUCTOR``, and the glass kinds from ``KIND_DIELECTRIC`` on, which
reflect and transmit on both faces); the other kinds' own parameters follow it. Kept in a
module of its own so that the kinds' kernels (``radiosity.scene.microfacet_kernels``)
and the dispatch (``radiosity.scene.material_kernels``) share them without importing each other.
"""

KD = 0  # 3 columns: diffuse reflectance (a rough plastic: its substrate's, scaled; see MF_DIFFUSE_NORM)
KS = 3  # 3 columns: specular reflectance of the Phong lobe
EXPONENT = 6  # Phong exponent n
EMISSION = 7  # 3 columns: emitted radiance
P_SPECULAR = 10  # probability that brdf_sample picks the Phong specular lobe (without Fresnel)
F0 = 11  # 3 columns: Schlick's F0 (with Fresnel)
HAS_FRESNEL = 14  # 1.0 if the diffuse part depends on the angles (a Fresnel term or a rough plastic)
KIND = 15  # which model: KIND_PHONG, KIND_ROUGH_PLASTIC, KIND_ROUGH_CONDUCTOR
MF_DISTRIBUTION = 16  # MF_GGX or MF_BECKMANN
MF_ALPHA = 17  # the microfacet roughness alpha (isotropic)
MF_ETA = 18  # 3 columns: a conductor's index eta per channel; a plastic's relative index in each
MF_K = 21  # 3 columns: a conductor's absorption k per channel
GLASS_TRANSMITTANCE = MF_K  # 3 columns: a glass's specular_transmittance (its eta in MF_ETA, reflectance in MF_SPECULAR)
MF_SPECULAR = 24  # 3 columns: specular_reflectance, the interface's scale
MF_SPECULAR_WEIGHT = 27  # a rough plastic's share of specular samples before Fresnel (Mitsuba's rule)
MF_DIFFUSE_NORM = 28  # a rough plastic: 1 / (2 int t(mu) mu dmu); KD holds kd' / eta^2 / MF_DIFFUSE_NORM
MF_TABLE = 29  # MF_TABLE_SIZE columns: a rough plastic's interface transmittance t(mu), mu = i / (size - 1)
MF_TABLE_SIZE = 64
NCOL = MF_TABLE + MF_TABLE_SIZE

KIND_PHONG = 0.0
KIND_ROUGH_PLASTIC = 1.0
KIND_ROUGH_CONDUCTOR = 2.0
KIND_DIELECTRIC = 3.0  # the glass kinds, from KIND_DIELECTRIC on (``radiosity.scene.glass_kernels``)
KIND_THIN_DIELECTRIC = 4.0
KIND_ROUGH_DIELECTRIC = 5.0
MF_GGX = 0.0
MF_BECKMANN = 1.0
