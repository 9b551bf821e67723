"""Every shading plugin against an independent reference (issue 31).

tests/reference/brdf_reference.py implements the models in numpy from the
published formulas (Burley 2012 and the Disney BRDF Explorer for the
principled BRDF; Blinn-Phong, Beer-Lambert, Fresnel, Stalling and Mallo lines),
not from Horizon's code. Random cases, with the edges where methods fail
(grazing angles, roughness 0 and 1, the specular peak, retro-reflection), go
through `horizon brdf` (the plugins' CPU references, which `horizon
shader-check` holds the GPU programs to, pixel by pixel) and must match to
max(1e-4 |expected|, 1e-6, 8 x the float32 sensitivity of the case).

Where ../shared/brdf/vectors_public.json exists, the numpy reference is also
checked against its expected values (reported as skipped when absent: the
check above does not depend on it).
"""
import json
import os
import subprocess
import sys
import unittest

import numpy as np

from hztest import HORIZON, SOURCE

sys.path.insert(0, os.path.join(SOURCE or os.path.join(os.path.dirname(__file__), "..", ".."), "tests", "reference"))
import brdf_reference as ref  # noqa: E402

SHARED = os.path.join(SOURCE or os.path.join(os.path.dirname(__file__), "..", ".."), "..", "shared", "brdf", "vectors_public.json")


def f32(x):
    return np.asarray(x, dtype=np.float32).astype(np.float64).tolist()


def hemisphere(rng, n, min_cos=0.0):
    while True:
        w = rng.normal(size=3)
        w /= np.linalg.norm(w)
        if w @ n > min_cos:
            return w


def cases(seed=7):
    rng = np.random.default_rng(seed)
    out = []
    n0 = np.array([0.0, 0.0, 1.0])

    def geometry(kind):
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        if kind == "z":
            n = n0
        l, v = hemisphere(rng, n, 0.02), hemisphere(rng, n, 0.02)
        if kind == "grazing":
            t = np.cross(n, rng.normal(size=3))
            t /= np.linalg.norm(t)
            l = t * np.sqrt(1 - 1e-6) + n * 1e-3
        elif kind == "peak":  # h = n: the specular peak
            v = hemisphere(rng, n, 0.2)
            l = 2 * (v @ n) * n - v
        elif kind == "retro":
            l = v.copy()
        x = rng.normal(size=3)
        return n, l, v, x, np.cross(n, x)

    for i in range(260):
        kind = ["generic", "generic", "z", "grazing", "peak", "retro"][i % 6]
        params = {k: float(rng.uniform()) for k in ref.PARAMS}
        if i % 5 == 0:
            params["roughness"] = [0.0, 1.0, 0.05][i % 3]
        if i % 7 == 0:
            for k in ("sheen", "clearcoat", "subsurface", "metallic"):
                params[k] = float(rng.choice([0.0, 1.0]))
        params = {k: f32(v) for k, v in params.items()}
        params["base_color"] = f32(rng.uniform(0, 1, 3))
        n, l, v, x, y = geometry(kind)
        model = "principled_isotropic" if i % 10 == 9 else "principled"
        c = {"id": f"p{i}", "model": model, "params": params, "N": f32(n), "L": f32(l), "V": f32(v)}
        if model == "principled":
            c["X"], c["Y"] = f32(x), f32(y)
        out.append(c)
    for i in range(40):
        n, l, v, _, _ = geometry("generic")
        col = lambda: f32(rng.uniform(0, 1, 3))  # noqa: E731
        s = f32(rng.uniform(1, 200))
        out.append({"id": f"l{i}", "model": "lambert", "albedo": col(), "N": f32(n), "L": f32(l), "V": f32(v)})
        out.append({"id": f"b{i}", "model": "blinn_phong", "N": f32(n), "L": f32(l), "V": f32(v), "kd": col(), "ks": col(), "ka": col(),
                    "shininess": s})
        out.append({"id": f"B{i}", "model": "blinn_phong_brdf", "N": f32(n), "L": f32(l), "V": f32(v), "kd": col(), "ks": col(), "shininess": s})
        out.append({"id": f"g{i}", "model": "beer_lambert", "alpha": col(), "length": f32(rng.uniform(0, 5)),
                    "concentration": f32(rng.uniform(0, 2))})
        out.append({"id": f"f{i}", "model": "fresnel_dielectric", "cos_i": f32(rng.uniform(0, 1)), "eta": f32(rng.uniform(0.5, 2.5))})
        out.append({"id": f"s{i}", "model": "fresnel_schlick", "f0": f32(rng.uniform(0, 1)), "cos_i": f32(rng.uniform(0, 1))})
        t = rng.normal(size=3)
        t /= np.linalg.norm(t)
        out.append({"id": f"t{i}", "model": "line_stalling", "T": f32(t), "L": f32(l), "V": f32(v), "kd": col(), "ks": col(), "ka": col(),
                    "shininess": f32(rng.uniform(1, 100)), "p_diffuse": f32(rng.uniform(1, 4))})
        out.append({"id": f"m{i}", "model": "line_mallo_diffuse", "T": f32(t), "L": f32(l), "V": f32(v), "kd": col()})
    return out


def evaluate_with_horizon(cs):
    p = subprocess.run([HORIZON, "brdf"], input="".join(json.dumps(c) + "\n" for c in cs), capture_output=True, text=True, timeout=120)
    if p.returncode != 0:
        raise AssertionError(p.stderr)
    answers = [json.loads(line) for line in p.stdout.splitlines()]
    assert len(answers) == len(cs), (len(answers), len(cs))
    return answers


class ShadingReferenceTest(unittest.TestCase):
    def test_every_shading_plugin_matches_the_independent_reference(self):
        cs = cases()
        answers = evaluate_with_horizon(cs)
        failures, by_model = [], {}
        for c, a in zip(cs, answers):
            self.assertEqual(a["id"], c["id"])
            self.assertNotIn("unsupported", a, f"no plugin implements {c['model']}")
            got = np.asarray(a["value"], dtype=np.float64)
            want = ref.evaluate(c)
            tol = np.maximum(np.maximum(1e-4 * np.abs(want), 1e-6), 8 * ref.sensitivity(c))
            by_model[c["model"]] = by_model.get(c["model"], 0) + 1
            if not (np.all(np.isfinite(got)) and np.all(np.abs(got - want) <= tol)):
                failures.append((c["id"], c["model"], got.tolist(), want.tolist()))
        self.assertEqual(failures[:5], [], f"{len(failures)} of {len(cs)} cases differ")
        self.assertEqual(set(by_model), set(ref.MODELS))

    def test_the_check_sees_each_principled_term(self):
        # Each lobe changes the answer somewhere in the cases: a plugin that
        # dropped one (sheen, clearcoat, subsurface, the tint, anisotropy)
        # would fail the test above.
        cs = [c for c in cases() if c["model"] == "principled"][:120]
        for term in ("sheen", "clearcoat", "subsurface", "specular_tint", "sheen_tint", "anisotropic", "metallic", "clearcoat_gloss"):
            changed = 0
            for c in cs:
                d = json.loads(json.dumps(c))
                d["params"][term] = 0.0 if c["params"][term] > 0.5 else 1.0
                want = ref.evaluate(c)
                tol = np.maximum(np.maximum(1e-4 * np.abs(want), 1e-6), 8 * ref.sensitivity(c))
                changed += bool(np.any(np.abs(ref.evaluate(d) - want) > tol))
            self.assertGreater(changed, 10, term)

    @unittest.skipUnless(os.path.exists(SHARED), "../shared/brdf (the contract's public vectors) is not beside this checkout")
    def test_the_reference_agrees_with_the_public_vectors(self):
        with open(SHARED) as f:
            vectors = json.load(f)
        vectors = vectors.get("cases", vectors) if isinstance(vectors, dict) else vectors
        checked = 0
        for c in vectors:
            if c["model"] not in ref.MODELS or c.get("check") == "finite_nonneg":
                continue
            got = ref.evaluate(c)
            want = np.asarray(c["expected"], dtype=np.float64)
            tol = np.asarray(c.get("tol", np.maximum(1e-4 * np.abs(want), 1e-6)), dtype=np.float64)
            self.assertTrue(np.all(np.abs(got - want) <= np.maximum(tol, 1e-9)), (c["id"], got.tolist(), want.tolist()))
            checked += 1
        self.assertGreater(checked, 250)


if __name__ == "__main__":
    unittest.main()
