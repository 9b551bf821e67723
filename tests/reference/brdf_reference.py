"""An independent reference of the shading models, in numpy (float64).

Written from the published formulas, not from Horizon's C++ or GLSL:
- the principled BRDF of Burley, "Physically-Based Shading at Disney" (SIGGRAPH
  2012 course notes) and the Disney BRDF Explorer's `disney.brdf` (diffuse with
  retro-reflection, the Hanrahan-Krueger-like subsurface, sheen, GTR2 anisotropic
  specular with separable Smith-GGX visibility, GTR1 clearcoat with F0 = 0.04 and
  alpha_g = 0.25), base colour in linear RGB;
- the domain guards the Horizon paper's BRDF needs (f = 0 below either horizon,
  parameters clamped to [0, 1], a tangent frame by Gram-Schmidt with a fallback,
  GTR1's normalisation continuous at alpha = 1);
- Lambert, Blinn-Phong (classic and normalised BRDF), Beer-Lambert, the exact
  unpolarised Fresnel reflectance of a dielectric (Born & Wolf), Schlick's
  approximation, Stalling et al.'s illuminated lines (1997) and Mallo et al.'s
  cylinder-averaged diffuse lines (2005).

Each function takes one case as the `horizon brdf` protocol gives it (a dict)
and returns RGB. tests/scripts/test_shading_reference.py drives it.
"""
import math

import numpy as np

PARAMS = ("subsurface", "metallic", "specular", "specular_tint", "roughness", "anisotropic", "sheen", "sheen_tint",
          "clearcoat", "clearcoat_gloss")


def unit(v):
    v = np.asarray(v, dtype=np.float64)
    s = np.max(np.abs(v))
    if not np.isfinite(s) or s == 0:
        return None
    v = v / s
    return v / np.sqrt(v @ v)


def clamp01(x):
    x = float(x)
    return min(max(x, 0.0), 1.0) if math.isfinite(x) else 0.0


def mix(a, b, t):
    return a + (b - a) * t


def schlick_weight(c):
    return min(max(1.0 - c, 0.0), 1.0) ** 5


def frame(n, x, y):
    """Tangent X' and bitangent Y' = N x X' (only squares of components enter)."""
    def perp(a):
        a = np.asarray(a, dtype=np.float64)
        if not np.all(np.isfinite(a)):
            return None
        p = a - (a @ n) * n
        la, lp = math.sqrt(a @ a), math.sqrt(p @ p)
        return p / lp if la > 0 and lp > 1e-6 * la else None
    t = perp(x)
    if t is None:
        b = perp(y)
        t = np.cross(b, n) if b is not None else None
    if t is None:  # any orthonormal basis: the isotropic terms do not depend on it
        a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        t = unit(a - (a @ n) * n)
    return t, np.cross(n, t)


def gtr1(cos_h, sin2_h, a):
    a = max(a, 1e-3)
    a2 = a * a
    if abs(a2 - 1.0) < 1e-8:
        return 1.0 / math.pi
    return (a2 - 1.0) / (math.pi * math.log(a2) * (sin2_h + a2 * cos_h * cos_h))


def principled(case, isotropic=False):
    p = {k: clamp01(case["params"].get(k, 0.0)) for k in PARAMS}
    if isotropic:
        p["anisotropic"] = 0.0
    c = np.array([clamp01(v) for v in case["params"]["base_color"]])
    n, l, v = unit(case["N"]), unit(case["L"]), unit(case["V"])
    if n is None or l is None or v is None:
        return np.zeros(3)
    nl, nv = n @ l, n @ v
    if nl <= 0 or nv <= 0:
        return np.zeros(3)
    h = unit(l + v)
    nh, lh = n @ h, l @ h
    x, y = frame(n, case.get("X", [1, 0, 0]), case.get("Y", [0, 1, 0]))
    lum = 0.3 * c[0] + 0.6 * c[1] + 0.1 * c[2]
    ctint = c / lum if lum > 0 else np.ones(3)
    cspec0 = mix(0.08 * p["specular"] * mix(np.ones(3), ctint, p["specular_tint"]), c, p["metallic"])
    csheen = mix(np.ones(3), ctint, p["sheen_tint"])
    fl, fv = schlick_weight(nl), schlick_weight(nv)
    fd90 = 0.5 + 2.0 * lh * lh * p["roughness"]
    fd = mix(1.0, fd90, fl) * mix(1.0, fd90, fv)
    fss90 = lh * lh * p["roughness"]
    fss = mix(1.0, fss90, fl) * mix(1.0, fss90, fv)
    ss = 1.25 * (fss * (1.0 / max(nl + nv, 1e-30) - 0.5) + 0.5)
    # Anisotropic GTR2 and its separable Smith visibility.
    aspect = math.sqrt(1.0 - 0.9 * p["anisotropic"])
    r2 = p["roughness"] ** 2
    ax, ay = max(1e-3, r2 / aspect), max(1e-3, r2 * aspect)
    hx, hy = h @ x, h @ y
    d = 1.0 / (math.pi * ax * ay * ((hx / ax) ** 2 + (hy / ay) ** 2 + nh * nh) ** 2)
    def vis(w):
        return 1.0 / (n @ w + math.sqrt(((w @ x) * ax) ** 2 + ((w @ y) * ay) ** 2 + (n @ w) ** 2))
    fh = schlick_weight(lh)
    fs = mix(cspec0, np.ones(3), fh)
    spec = d * vis(l) * vis(v) * fs
    # Clearcoat: GTR1, F0 = 0.04, Smith-GGX with alpha 0.25, weight 0.25.
    sin2_h = float(np.cross(n, h) @ np.cross(n, h))
    dr = gtr1(nh, sin2_h, mix(0.1, 0.001, p["clearcoat_gloss"]))
    fr = mix(0.04, 1.0, fh)
    def vis_g(cos, a):
        return 1.0 / (cos + math.sqrt(a * a + cos * cos - a * a * cos * cos))
    coat = 0.25 * p["clearcoat"] * dr * fr * vis_g(nl, 0.25) * vis_g(nv, 0.25)
    sheen = fh * p["sheen"] * csheen
    diffuse = (1.0 / math.pi) * mix(fd, ss, p["subsurface"]) * c
    return (diffuse + sheen) * (1.0 - p["metallic"]) + spec + coat


def lambert(case):
    n, l, v = unit(case["N"]), unit(case["L"]), unit(case["V"])
    if n is None or l is None or v is None or n @ l <= 0 or n @ v <= 0:
        return np.zeros(3)
    return np.asarray(case["albedo"], dtype=np.float64) / math.pi


def blinn_phong(case):
    n, l, v = unit(case["N"]), unit(case["L"]), unit(case["V"])
    s = max(float(case["shininess"]), 1.0)
    ka, kd, ks = (np.asarray(case[k], dtype=np.float64) for k in ("ka", "kd", "ks"))
    nl = max(n @ l, 0.0)
    spec = 0.0
    if n @ l > 0 and n @ v > 0:
        spec = max(n @ unit(l + v), 0.0) ** s
    return ka + kd * nl + ks * spec


def blinn_phong_brdf(case):
    n, l, v = unit(case["N"]), unit(case["L"]), unit(case["V"])
    if n @ l <= 0 or n @ v <= 0:
        return np.zeros(3)
    s = max(float(case["shininess"]), 1.0)
    kd, ks = np.asarray(case["kd"], dtype=np.float64), np.asarray(case["ks"], dtype=np.float64)
    return kd / math.pi + ks * (s + 8) / (8 * math.pi) * max(n @ unit(l + v), 0.0) ** s


def beer_lambert(case):
    a = np.maximum(np.asarray(case["alpha"], dtype=np.float64), 0)
    return np.exp(-a * max(float(case["length"]), 0) * max(float(case["concentration"]), 0))


def fresnel_dielectric(case):
    # cos_i in [0, 1] (the contract's domain: the incident side is the one
    # eta = n_t / n_i describes; eta < 1 is the inside, with total reflection).
    ci, eta = min(max(float(case["cos_i"]), 0.0), 1.0), float(case["eta"])
    s2t = (1 - ci * ci) / (eta * eta)
    if s2t >= 1:
        return np.ones(3)
    ct = math.sqrt(1 - s2t)
    rs = (ci - eta * ct) / (ci + eta * ct)
    rp = (eta * ci - ct) / (eta * ci + ct)
    return np.full(3, 0.5 * (rs * rs + rp * rp))


def fresnel_schlick(case):
    f0, ci = float(case["f0"]), float(case["cos_i"])
    return np.full(3, f0 + (1 - f0) * schlick_weight(ci))


def line_stalling(case):
    t, l, v = unit(case["T"]), unit(case["L"]), unit(case["V"])
    lt, vt = l @ t, v @ t
    ln = math.sqrt(max(1 - lt * lt, 0))
    vr = ln * math.sqrt(max(1 - vt * vt, 0)) - lt * vt
    ka, kd, ks = (np.asarray(case[k], dtype=np.float64) for k in ("ka", "kd", "ks"))
    return ka + kd * ln ** float(case.get("p_diffuse", 1.0)) + ks * max(vr, 0.0) ** float(case["shininess"])


def line_mallo_diffuse(case):
    t, l, v = unit(case["T"]), unit(case["L"]), unit(case["V"])
    kd = np.asarray(case["kd"], dtype=np.float64)
    lp, vp = l - (l @ t) * t, v - (v @ t) * t
    sin_l = math.sqrt(max(lp @ lp, 0))
    if math.sqrt(vp @ vp) < 1e-12 or sin_l < 1e-12:
        return kd * sin_l / math.pi
    ca = float(np.clip((lp @ vp) / (sin_l * math.sqrt(vp @ vp)), -1, 1))
    a = math.acos(ca)
    return kd * sin_l * (math.sin(a) + (math.pi - a) * ca) / 4


MODELS = {"principled": principled, "principled_isotropic": lambda c: principled(c, True), "lambert": lambert,
          "blinn_phong": blinn_phong, "blinn_phong_brdf": blinn_phong_brdf, "beer_lambert": beer_lambert,
          "fresnel_dielectric": fresnel_dielectric, "fresnel_schlick": fresnel_schlick, "line_stalling": line_stalling,
          "line_mallo_diffuse": line_mallo_diffuse}


def evaluate(case):
    return np.asarray(MODELS[case["model"]](case), dtype=np.float64)


def sensitivity(case, trials=8, rel=2.0 ** -23, seed=0):
    """The largest change of the result when every vector and scalar input is
    perturbed by `rel` relative: what a careful float32 evaluation cannot avoid."""
    rng = np.random.default_rng(seed)
    base = evaluate(case)
    worst = np.zeros(3)
    for _ in range(trials):
        c = {}
        for k, val in case.items():
            if k in ("N", "L", "V", "X", "Y", "T"):
                a = np.asarray(val, dtype=np.float64)
                c[k] = (a * (1 + rel * rng.uniform(-1, 1, a.shape))).tolist()
            else:
                c[k] = val
        worst = np.maximum(worst, np.abs(evaluate(c) - base))
    return worst
