"""The glTF 2.0 metallic-roughness BRDF in float64 NumPy (docs/SHADING.md, "PBR"): the CPU twin of
``shaders/bsdf_pbr.glsl``'s ``pbr_brdf``, written from the specification's appendix B, for the
reference tracer's Whitted shading and the white-furnace albedos the tests and docs compare with.

Vectors are (..., 3) arrays, unit; ``n`` the shading normal on the side of ``wo``.
"""

from __future__ import annotations

import functools

import numpy as np

MIN_ALPHA = 1.0e-3  # GGX α of roughness 0 (shaders/bsdf_pbr.glsl's PBR_MIN_ALPHA)


def alpha_of(roughness: float | np.ndarray) -> np.ndarray:
    """GGX α of perceptual roughness: roughness², at least MIN_ALPHA."""
    return np.maximum(np.square(roughness), MIN_ALPHA)


def f0_of(ior: float | np.ndarray) -> np.ndarray:
    """The dielectric's normal-incidence reflectance ((ior − 1)/(ior + 1))²."""
    return np.square((np.asarray(ior, dtype=np.float64) - 1.0) / (np.asarray(ior, dtype=np.float64) + 1.0))


def schlick_weight(c: np.ndarray) -> np.ndarray:
    """(1 − c)⁵, c clamped to [0, 1]."""
    return (1.0 - np.clip(c, 0.0, 1.0)) ** 5


def dielectric_fresnel(f0: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Schlick's F0 + (1 − F0)(1 − c)⁵; 0 where F0 is 0 (ior 1: no interface, nothing reflects)."""
    f0 = np.asarray(f0, dtype=np.float64)
    return np.where(f0 > 0.0, f0 + (1.0 - f0) * schlick_weight(c), 0.0)


def fresnel(base: np.ndarray, metallic: np.ndarray, f0: np.ndarray, c: np.ndarray) -> np.ndarray:
    """(..., 3) the specular Fresnel at cos θ = c: Schlick's with F0 from ior for the dielectric, the
    base colour's for the metal, mixed by metallic."""
    s = schlick_weight(c)[..., None]
    m = np.asarray(metallic, dtype=np.float64)[..., None]
    return (1.0 - m) * dielectric_fresnel(f0, c)[..., None] + m * (base + (1.0 - base) * s)


def brdf(
    base: np.ndarray,
    metallic: np.ndarray,
    alpha: np.ndarray,
    f0: np.ndarray,
    transmission: np.ndarray,
    n: np.ndarray,
    wo: np.ndarray,
    wi: np.ndarray,
    spec_share: float | np.ndarray = 1.0,
) -> np.ndarray:
    """(..., 3) f(wo → wi), no cosine: (1 − metallic)·[(1 − F(n·wo))(1 − transmission) base/π +
    spec_share·F·D·V] + metallic·F_metal·D·V, F Schlick's at the half vector but the diffuse share's at
    the view (docs/SHADING.md, "PBR": the specification's half-vector weight reflects up to 1.5× the
    light a white dielectric receives at grazing views), D GGX, V Smith's height-correlated term; 0
    below either horizon."""
    base = np.asarray(base, dtype=np.float64)
    n_o = np.sum(n * wo, axis=-1)
    n_i = np.sum(n * wi, axis=-1)
    ok = (n_o > 0.0) & (n_i > 0.0)
    h = wo + wi
    h = h / np.maximum(np.linalg.norm(h, axis=-1, keepdims=True), 1e-300)
    s = schlick_weight(np.sum(wo * h, axis=-1))
    a2 = np.square(np.asarray(alpha, dtype=np.float64))
    n_h = np.clip(np.sum(n * h, axis=-1), 0.0, 1.0)
    k = n_h * n_h * (a2 - 1.0) + 1.0
    d = a2 / (np.pi * k * k)
    no, ni = np.maximum(n_o, 0.0), np.maximum(n_i, 0.0)
    v = 0.5 / np.maximum(ni * np.sqrt(no * no * (1.0 - a2) + a2) + no * np.sqrt(ni * ni * (1.0 - a2) + a2), 1e-300)
    spec = (d * v)[..., None]
    fd = dielectric_fresnel(f0, np.sum(wo * h, axis=-1))[..., None]
    fv = dielectric_fresnel(f0, n_o)[..., None]
    fm = base + (1.0 - base) * s[..., None]
    t = np.asarray(transmission, dtype=np.float64)[..., None]
    m = np.asarray(metallic, dtype=np.float64)[..., None]
    share = np.asarray(spec_share, dtype=np.float64)[..., None] if np.ndim(spec_share) else spec_share
    dielectric = (1.0 - fv) * (1.0 - t) * base / np.pi + share * fd * spec
    return np.where(ok[..., None], (1.0 - m) * dielectric + m * fm * spec, 0.0)


def directional_albedo(
    base: tuple[float, float, float],
    metallic: float,
    roughness: float,
    cos_o: float,
    ior: float = 1.5,
    samples: int = 1 << 16,
    seed: int = 0,
) -> np.ndarray:
    """(3,) ∫ f(wo → wi) cos θi dωi at a view of cos θo = ``cos_o``, by Monte Carlo: half the samples
    cosine-distributed, half from GGX's normals (D(m) cos θm, reflected), combined by the balance
    heuristic (one-sample mixture), so both the diffuse and a narrow specular lobe converge."""
    rng = np.random.default_rng(seed)
    a = float(alpha_of(roughness))
    n = np.array([0.0, 0.0, 1.0])
    wo = np.array([np.sqrt(max(0.0, 1.0 - cos_o * cos_o)), 0.0, cos_o])
    u1, u2, pick = rng.random(samples), rng.random(samples), rng.random(samples) < 0.5
    phi = 2.0 * np.pi * u2
    # cosine directions
    r = np.sqrt(u1)
    wc = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(np.maximum(0.0, 1.0 - u1))], axis=-1)
    # GGX normals: tan²θ = α² u / (1 − u)
    cos_m = 1.0 / np.sqrt(1.0 + a * a * u1 / np.maximum(1.0 - u1, 1e-300))
    sin_m = np.sqrt(np.maximum(0.0, 1.0 - cos_m * cos_m))
    m = np.stack([sin_m * np.cos(phi), sin_m * np.sin(phi), cos_m], axis=-1)
    wg = 2.0 * np.sum(wo * m, axis=-1, keepdims=True) * m - wo
    wi = np.where(pick[:, None], wc, wg)
    cos_i = wi[:, 2]
    h = wo + wi
    h = h / np.maximum(np.linalg.norm(h, axis=-1, keepdims=True), 1e-300)
    n_h = np.clip(h[:, 2], 0.0, 1.0)
    k = n_h * n_h * (a * a - 1.0) + 1.0
    d = a * a / (np.pi * k * k)
    p_ggx = d * n_h / np.maximum(4.0 * np.abs(np.sum(wo * h, axis=-1)), 1e-300)
    pdf = 0.5 * np.maximum(cos_i, 0.0) / np.pi + 0.5 * p_ggx
    f = brdf(np.asarray(base, float), np.asarray(metallic), np.asarray(a), f0_of(ior), np.asarray(0.0), n, wo, wi)
    with np.errstate(invalid="ignore", divide="ignore"):
        w = np.where((cos_i > 0.0)[:, None] & (pdf > 0.0)[:, None], f * cos_i[:, None] / pdf[:, None], 0.0)
    return w.mean(axis=0)


@functools.cache
def albedo_table(metallic: float, roughness: float, points: int = 25, samples: int = 1 << 17) -> tuple:
    """(cos θo grid from 0.02 to 1, the white material's directional albedo there): the curve a white
    furnace's sphere shows, pixel by pixel."""
    mu = np.linspace(0.02, 1.0, points)
    albedo = np.array([directional_albedo((1.0, 1.0, 1.0), metallic, roughness, c, samples=samples)[0] for c in mu])
    return mu, albedo


def furnace_radiance(cos_o: np.ndarray, metallic: float, roughness: float) -> np.ndarray:
    """The radiance a convex white sphere of this material shows under a uniform environment of
    radiance 1 at views of cos θo = ``cos_o``: its directional albedo there (no light bounces back
    onto a convex body), interpolated in :func:`albedo_table`."""
    mu, albedo = albedo_table(metallic, roughness)
    return np.interp(np.clip(cos_o, 0.0, 1.0), mu, albedo)
