"""A Mitsuba 3 BSDF for any material spec of the toolkit.

Usage::

    import mitsuba as mi
    mi.set_variant("llvm_ad_rgb")          # or "scalar_rgb", or any RGB variant
    import reflectance.mitsuba
    reflectance.mitsuba.register()         # registers the BSDF type "reflectance"
    bsdf = mi.load_dict({"type": "reflectance", "spec": "merl:blue-acrylic"})

or in an XML scene ``<bsdf type="reflectance"><string name="spec" value="merl:chrome"/></bsdf>``.

Parameters of the plugin:

``spec`` (string, required)
    Any material spec (``merl:<name>``, ``nielsen:<name>``, a ``.binary`` file, an analytic model,
    ``pca:``/``wavelet:`` forms). A bad spec raises ``ValueError`` in the plugin's constructor;
    ``mi.load_dict``/``mi.load_string`` re-raise it as Mitsuba's ``RuntimeError`` whose message
    holds the ``ValueError`` and its text (Mitsuba wraps every plugin's construction errors).
``interpolation`` (string, ``"trilinear"`` or ``"nearest"``, default trilinear)
    Lookup in the tabulated BRDF: trilinear between the MERL grid nodes (a Dr.Jit texture), or the
    bin that contains the query with the MERL reference reader's indexing (a Dr.Jit gather).

How it works. The material is tabulated on the MERL grid by the Rust crates (``Material.tabulate``)
and uploaded once; Rusinkiewicz half/difference angles of each (wi, wo) pair are computed with
Dr.Jit operations and looked up in the table. Directions are sampled from the importance tables of
thesis appendix A.2.4 as built by the ``render`` crate (``Material.importance_tables``): per row of
the viewer's polar angle θr a marginal over the light's polar angle θi and, per (θr, θi), a
conditional over the azimuth difference φdiff, each drawn in constant time from its alias table
(two reads instead of a CDF search, which cost a third of the render); within a cell the
direction is uniform in solid angle, and a small fraction of cosine-weighted samples
(``defensive``) keeps the density positive wherever the BRDF is. The density is evaluated exactly
from the same tables, so the plugin combines with Mitsuba's light sampling by multiple importance
sampling. The BSDF is one-sided (front side), a glossy reflection.

Conventions: Mitsuba's ``si.wi`` points to the viewer and ``wo`` to the light; the toolkit's BRDF
takes ``(wi=light, wo=viewer)``. The table is isotropic and φd is folded by reciprocity, so the
lookup is the same either way.
"""

from __future__ import annotations

import math

import numpy as np

from . import _native

__all__ = ["SPHERE_LIGHT", "bsdf_class", "register", "sphere_scene"]

_CLASSES: dict = {}


def _has(props, key):
    """Whether Mitsuba properties hold `key` (``in`` since Mitsuba 3.7, ``has_property`` before)."""
    try:
        return key in props
    except TypeError:
        return props.has_property(key)


def _make_class(mi, dr):
    """The BSDF class for the current Mitsuba variant (classes are bound to a variant)."""

    Float = mi.Float
    UInt32 = mi.UInt32
    Int32 = mi.Int32
    PI = math.pi
    HALF_PI = 0.5 * math.pi

    scalar = mi.variant().startswith("scalar")

    def gather(src, idx, active=True):
        """dr.gather of float32 values; plain indexing in scalar variants (one lane per call)."""
        if scalar:
            return float(src[int(idx)]) if active else 0.0
        return dr.gather(Float, src, idx, active)

    def store(a):
        """A flat float32 array for dr.gather (a dynamic array in every variant, scalar too)."""
        return mi.TensorXf(np.ascontiguousarray(np.asarray(a, dtype=np.float32).ravel())).array

    class ReflectanceBSDF(mi.BSDF):
        """A tabulated measured or analytic BRDF of the reflectance toolkit."""

        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            if not _has(props, "spec"):
                raise ValueError("the reflectance BSDF needs a 'spec' string parameter")
            self.spec = str(props["spec"])
            interp = str(props["interpolation"]) if _has(props, "interpolation") else "trilinear"
            if interp not in ("trilinear", "nearest"):
                raise ValueError(f"interpolation '{interp}': expected 'trilinear' or 'nearest'")
            self.interpolation = interp
            material = _native.load(self.spec)  # ValueError for a bad spec
            self.material = material
            table = np.maximum(material.tabulate(), 0.0).astype(np.float32)
            self._nth, self._ntd, self._npd = table.shape[:3]
            if interp == "trilinear":
                # φd is periodic (reciprocity): repeat bin 0 after the last so that a clamped
                # texture interpolates across the seam.
                padded = np.concatenate([table, table[:, :, :1, :]], axis=2)
                self._texture = mi.Texture3f(
                    mi.TensorXf(np.ascontiguousarray(padded)),
                    use_accel=False,
                    filter_mode=dr.FilterMode.Linear,
                    wrap_mode=dr.WrapMode.Clamp,
                )
            else:
                self._flat = store(table)
            tables = material.importance_tables()
            self._nr, self._na, self._nk = tables["cell_density"].shape
            self._cell_density = store(tables["cell_density"])
            self._marginal = store(tables["marginal_alias"])
            self._conditional = store(tables["conditional_alias"])
            self._total = store(tables["row_totals"])
            self._defensive = float(tables["defensive"])
            edges = np.cos(np.arange(self._na + 1) * (HALF_PI / self._na))
            self._cos_edges = store(edges)
            self.m_flags = mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.FrontSide
            self.m_components = [self.m_flags]

        # -- the tabulated BRDF -------------------------------------------------------------

        def _half_diff(self, wl, wv):
            """(θh, θd, φd) of light direction `wl` and viewer direction `wv` (local frame).

            Polar angles come from atan2 rather than acos: near the specular peak θh is a
            fraction of a MERL bin (the first bin ends at θh = 1.9e-4 rad), far below acos's
            float32 resolution there."""
            h = wl + wv
            rho = dr.sqrt(h.x * h.x + h.y * h.y)
            norm = dr.sqrt(rho * rho + h.z * h.z)
            theta_h = dr.atan2(rho, h.z)
            has_phi = rho > 0
            # Both sides of dr.select are evaluated: in scalar variants (Python floats) a zero
            # denominator would raise, so the unused side divides by 1.
            rho_safe = dr.select(has_phi, rho, 1.0)
            c = dr.select(has_phi, h.x / rho_safe, 1.0)
            s = dr.select(has_phi, h.y / rho_safe, 0.0)
            # rotate wl about z by -φh, then about y by -θh
            x1 = wl.x * c + wl.y * s
            y1 = -wl.x * s + wl.y * c
            z1 = wl.z
            # (norm is 0 only for opposite directions, which never reach a lookup; kept finite
            # for scalar variants, which would raise)
            norm = dr.maximum(norm, 1e-30)
            ct = h.z / norm
            st = rho / norm
            dx = x1 * ct - z1 * st
            dz = x1 * st + z1 * ct
            theta_d = dr.atan2(dr.sqrt(dx * dx + y1 * y1), dz)
            phi_d = dr.atan2(y1, dx)
            return theta_h, theta_d, phi_d

        def _lookup(self, wl, wv, active):
            theta_h, theta_d, phi_d = self._half_diff(wl, wv)
            # φd folded into [0, π) by reciprocity
            p = phi_d - PI * dr.floor(phi_d / PI)
            if self.interpolation == "trilinear":
                uh = dr.clip(dr.sqrt(dr.maximum(theta_h, 0.0) / HALF_PI) * self._nth, 0.0, self._nth - 1)
                ud = dr.clip(theta_d / HALF_PI * self._ntd, 0.0, self._ntd - 1)
                up = dr.clip(p / PI * self._npd, 0.0, float(self._npd))
                pos = mi.Point3f(
                    (up + 0.5) / (self._npd + 1), (ud + 0.5) / self._ntd, (uh + 0.5) / self._nth
                )
                v = self._texture.eval(pos, active)
                return mi.Color3f(v[0], v[1], v[2])
            # the MERL reference reader's bins
            th_deg = dr.maximum(theta_h, 0.0) / HALF_PI * self._nth
            i_th = dr.clip(Int32(dr.sqrt(th_deg * self._nth)), 0, self._nth - 1)
            i_td = dr.clip(Int32(theta_d / HALF_PI * self._ntd), 0, self._ntd - 1)
            i_pd = dr.clip(Int32(p / PI * self._npd), 0, self._npd - 1)
            idx = UInt32((i_th * self._ntd + i_td) * self._npd + i_pd) * 3
            return mi.Color3f(
                gather(self._flat, idx, active),
                gather(self._flat, idx + 1, active),
                gather(self._flat, idx + 2, active),
            )

        # -- the importance tables (thesis A.2.4) -------------------------------------------

        def _row(self, wv):
            theta_r = dr.acos(dr.clip(wv.z, -1.0, 1.0))
            return dr.minimum(UInt32(theta_r / HALF_PI * self._nr), self._nr - 1)

        def _table_density(self, wv, wl, active):
            """The tables' density of the cell holding `wl` (before the defensive mixture) and
            whether the viewer's row has weight (where it has none, the cosine density applies).

            The cells are uniform in θi and in the azimuth difference |φl − φv| ∈ [0, π]; both
            are taken with acos (of wl.z and of the cosine of the azimuth difference), exact
            enough at every interior cell edge, where the arguments are away from ±1."""
            r = self._row(wv)
            usable = active & (gather(self._total, r, active) > 0)
            theta_l = dr.acos(dr.clip(wl.z, -1.0, 1.0))
            a = dr.minimum(UInt32(theta_l / HALF_PI * self._na), self._na - 1)
            rho2 = (wl.x * wl.x + wl.y * wl.y) * (wv.x * wv.x + wv.y * wv.y)
            # a direction on the pole has no azimuth: any cell of its (zero-measure) ring will do
            cos_d = dr.select(rho2 > 0, (wl.x * wv.x + wl.y * wv.y) * dr.rsqrt(dr.select(rho2 > 0, rho2, 1.0)), 1.0)
            d = dr.acos(dr.clip(cos_d, -1.0, 1.0))
            k = dr.minimum(UInt32(d / PI * self._nk), self._nk - 1)
            density = gather(self._cell_density, (r * self._na + a) * self._nk + k, usable)
            return density, usable

        def _pdf(self, wv, wl, active):
            active = active & (wv.z > 0) & (wl.z > 0)
            cos_pdf = dr.maximum(wl.z, 0.0) / PI
            density, usable = self._table_density(wv, wl, active)
            table = dr.select(usable, density, cos_pdf)
            mix = (1.0 - self._defensive) * table + self._defensive * cos_pdf
            return dr.select(active, mix, 0.0)

        def _sample_direction(self, wv, sample1, sample2, active):
            """A light direction drawn from the tables (alias tables over θi, then over the
            azimuth difference; uniform in solid angle within the cell) or, for the defensive
            fraction of `sample1` and rows without weight, from the cosine density; returned with
            its density (the mixture of both, `_pdf`)."""
            r = self._row(wv)
            total = gather(self._total, r, active)
            use_table = active & (total > 0) & (sample1 >= self._defensive)
            # sample1 beyond the defensive fraction, rescaled, chooses the sign of φdiff
            u_sign = (sample1 - self._defensive) / (1.0 - self._defensive)
            na, nk = self._na, self._nk
            # θi cell: alias table of row r; the rest of the number places θ within the cell
            x = dr.clip(sample2.x, 0.0, 0.99999994) * na
            i = dr.minimum(UInt32(x), na - 1)
            f = x - Float(i)
            slot = (r * na + i) * 2
            keep_t = gather(self._marginal, slot, use_table)
            keep = f < keep_t
            a = dr.select(keep, i, UInt32(gather(self._marginal, slot + 1, use_table)))
            v1 = dr.select(keep, f / dr.maximum(keep_t, 1e-30), (f - keep_t) / dr.maximum(1.0 - keep_t, 1e-30))
            # φdiff cell: alias table of (r, a)
            y = dr.clip(sample2.y, 0.0, 0.99999994) * nk
            j = dr.minimum(UInt32(y), nk - 1)
            g = y - Float(j)
            pair = ((r * na + a) * nk + j) * 2
            keep_t = gather(self._conditional, pair, use_table)
            keep = g < keep_t
            k = dr.select(keep, j, UInt32(gather(self._conditional, pair + 1, use_table)))
            v2 = dr.select(keep, g / dr.maximum(keep_t, 1e-30), (g - keep_t) / dr.maximum(1.0 - keep_t, 1e-30))
            c0 = gather(self._cos_edges, a, use_table)
            c1 = gather(self._cos_edges, a + 1, use_table)
            cos_t = c0 - dr.clip(v1, 0.0, 1.0) * (c0 - c1)
            sin_t = dr.safe_sqrt(1.0 - cos_t * cos_t)
            phi_d = (Float(k) + dr.clip(v2, 0.0, 1.0)) * (PI / nk)
            s, c = dr.sincos(dr.select(u_sign < 0.5, -phi_d, phi_d))
            # rotate the viewer's azimuth (cos φv, sin φv) by φdiff, without an atan2
            rho_v = dr.sqrt(wv.x * wv.x + wv.y * wv.y)
            has_phi = rho_v > 0
            inv = dr.select(has_phi, 1.0 / dr.select(has_phi, rho_v, 1.0), 0.0)
            cv = dr.select(has_phi, wv.x * inv, 1.0)
            sv = wv.y * inv
            table_dir = mi.Vector3f(sin_t * (cv * c - sv * s), sin_t * (sv * c + cv * s), cos_t)
            cos_dir = mi.warp.square_to_cosine_hemisphere(sample2)
            wl = dr.select(use_table, table_dir, cos_dir)
            # the density of the cell the direction falls in, as `_pdf` finds it (a direction
            # drawn on a cell edge is given the density `pdf()` reports for it)
            return wl, self._pdf(wv, wl, active)

        # -- the mi.BSDF interface ----------------------------------------------------------

        def eval(self, ctx, si, wo, active=True):
            wv = si.wi
            active = active & (mi.Frame3f.cos_theta(wv) > 0) & (mi.Frame3f.cos_theta(wo) > 0)
            if not ctx.is_enabled(mi.BSDFFlags.GlossyReflection):
                return mi.Color3f(0.0)
            f = self._lookup(wo, wv, active)
            return dr.select(active, f * mi.Frame3f.cos_theta(wo), mi.Color3f(0.0))

        def pdf(self, ctx, si, wo, active=True):
            if not ctx.is_enabled(mi.BSDFFlags.GlossyReflection):
                return Float(0.0)
            return self._pdf(si.wi, wo, active)

        def eval_pdf(self, ctx, si, wo, active=True):
            return self.eval(ctx, si, wo, active), self.pdf(ctx, si, wo, active)

        def sample(self, ctx, si, sample1, sample2, active=True):
            wv = si.wi
            active = active & (mi.Frame3f.cos_theta(wv) > 0)
            if not ctx.is_enabled(mi.BSDFFlags.GlossyReflection):
                active = active & False
            bs = dr.zeros(mi.BSDFSample3f)
            wo, pdf = self._sample_direction(wv, sample1, sample2, active)
            active = active & (pdf > 0) & (mi.Frame3f.cos_theta(wo) > 0)
            bs.wo = wo
            bs.pdf = dr.select(active, pdf, 0.0)
            bs.eta = 1.0
            bs.sampled_type = UInt32(+mi.BSDFFlags.GlossyReflection)
            bs.sampled_component = UInt32(0)
            f = self._lookup(wo, wv, active) * mi.Frame3f.cos_theta(wo)
            weight = dr.select(active, f / dr.maximum(pdf, 1e-30), mi.Color3f(0.0))
            return bs, weight

        def traverse(self, callback):
            pass

        def parameters_changed(self, keys):
            pass

        def to_string(self):
            return f"ReflectanceBSDF[spec={self.spec!r}, interpolation={self.interpolation!r}]"

    return ReflectanceBSDF


def bsdf_class():
    """The BSDF class for the active Mitsuba variant (``mi.set_variant`` must have been called)."""
    import drjit as dr
    import mitsuba as mi

    variant = mi.variant()
    if variant is None:
        raise RuntimeError("set a Mitsuba variant first, e.g. mi.set_variant('llvm_ad_rgb')")
    if variant not in _CLASSES:
        _CLASSES[variant] = _make_class(mi, dr)
    return _CLASSES[variant]


def register(name: str = "reflectance") -> None:
    """Registers the BSDF with Mitsuba under the type ``name`` (default ``"reflectance"``) for the
    active variant; call again after switching variants."""
    import mitsuba as mi

    cls = bsdf_class()
    mi.register_bsdf(name, lambda props: cls(props))


#: Where `gantry render sphere` puts its point light (render::sphere_scene).
SPHERE_LIGHT = (-4.0, 4.0, 6.0)


def sphere_scene(bsdf: dict, size: int = 256, spp: int = 16, integrator: dict | None = None) -> dict:
    """The figure of ``gantry render sphere`` as a Mitsuba scene dict: a unit sphere at the origin
    seen from (0, 0, 4) with a 32° field of view, one point light at :data:`SPHERE_LIGHT` whose
    intensity gives irradiance π at the sphere (a white Lambertian reaches radiance 1), black
    background, box pixel filter. ``bsdf`` is a BSDF dict (e.g. ``{"type": "reflectance",
    "spec": "merl:chrome"}``); the integrator defaults to Mitsuba's ``direct``."""
    import mitsuba as mi

    d = math.sqrt(sum(c * c for c in SPHERE_LIGHT)) - 1.0
    return {
        "type": "scene",
        "integrator": integrator or {"type": "direct"},
        "sensor": {
            "type": "perspective",
            "fov": 32.0,
            "fov_axis": "x",
            "to_world": mi.ScalarTransform4f().look_at(
                origin=[0.0, 0.0, 4.0], target=[0.0, 0.0, 0.0], up=[0.0, 1.0, 0.0]
            ),
            "film": {
                "type": "hdrfilm",
                "width": size,
                "height": size,
                "pixel_format": "rgb",
                "rfilter": {"type": "box"},
            },
            "sampler": {"type": "independent", "sample_count": spp},
        },
        "sphere": {"type": "sphere", "center": [0.0, 0.0, 0.0], "radius": 1.0, "bsdf": bsdf},
        "light": {
            "type": "point",
            "position": list(SPHERE_LIGHT),
            "intensity": {"type": "rgb", "value": [math.pi * d * d] * 3},
        },
    }
