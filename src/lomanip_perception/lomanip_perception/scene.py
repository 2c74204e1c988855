"""Scene object geometry for perception: primitives, canonical frames, closest-surface projection.

Why: contact transfer ends by projecting each transferred hand/foot point onto the closest surface
of the real scene object (paper Sec. III-A2, "to avoid penetrations"); the scene objects come from
the simulator as unions of primitives posed in the object frame (lomanip_msgs/SceneObject). This
module is that geometry, numpy only.

Conventions: primitive sizes follow MuJoCo (box = half extents, sphere = (r,), cylinder/capsule =
(r, half length) along the primitive's local z); quaternions are (w, x, y, z) and converted only
through lomanip_sim.frames. The *canonical frame* of an object is the axis-aligned bounding box of
its primitives in the object frame: canonical coordinates c = (p - centre) / half_extent lie in
[-1, 1]^3. Two instances of one class share semantics in canonical coordinates (the handle of any
trolley is near c = (-1, 0, 1)); the synthetic matcher and the benchmark's ground truth use that.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from lomanip_sim import frames

PRIMITIVE_TYPES = ("box", "sphere", "cylinder", "capsule")
#: m: a limb's contact goes to a surface facing its elbow / knee only if that surface is at most this
#: much farther than the closest one (ObjectGeometry.project_to_surface_facing)
FACING_MAX_DETOUR = 0.03


@dataclass(frozen=True)
class Primitive:
    """One primitive posed in its object's frame (MuJoCo size convention)."""

    type: str
    size: tuple[float, ...]
    pos: np.ndarray = field(default_factory=lambda: np.zeros(3))
    quat: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))
    rgba: tuple[float, float, float, float] | None = None  # only the synthetic renderer reads it

    def __post_init__(self):
        if self.type not in PRIMITIVE_TYPES:
            raise ValueError(f"unknown primitive type {self.type!r}; expected one of {PRIMITIVE_TYPES}")

    @property
    def R(self) -> np.ndarray:
        return frames.quat_to_matrix(self.quat)

    def local_half_extent(self) -> np.ndarray:
        """Half extents of the primitive's own bounding box (in its local axes)."""
        s = self.size
        if self.type == "box":
            return np.array(s[:3], dtype=float)
        if self.type == "sphere":
            return np.full(3, s[0])
        if self.type == "cylinder":
            return np.array([s[0], s[0], s[1]])
        return np.array([s[0], s[0], s[1] + s[0]])  # capsule

    def signed_distance_local(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For points q (N,3) in the primitive frame: signed distance (N,), closest surface point
        (N,3) and outward normal (N,3), all in the primitive frame."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        t, s = self.type, self.size
        if t == "box":
            h = np.asarray(s[:3], dtype=float)
            d = np.abs(q) - h
            outside = np.any(d > 0, axis=1)
            c = np.clip(q, -h, h)
            diff = q - c
            dist = np.linalg.norm(diff, axis=1)
            normal = np.zeros_like(q)
            with np.errstate(invalid="ignore", divide="ignore"):
                normal[outside] = diff[outside] / dist[outside, None]
            inside = ~outside
            if np.any(inside):
                k = np.argmax(d[inside], axis=1)
                idx = np.nonzero(inside)[0]
                sign = np.where(q[idx, k] >= 0, 1.0, -1.0)
                c[idx, k] = sign * h[k]
                dist[idx] = d[idx, k]  # negative
                normal[idx, k] = sign
            return dist, c, normal
        if t == "sphere":
            r = s[0]
            n = np.linalg.norm(q, axis=1)
            u = _safe_unit(q, n, np.array([0.0, 0.0, 1.0]))
            return n - r, u * r, u
        if t == "capsule":
            r, hz = s[0], s[1]
            a = np.zeros_like(q)
            a[:, 2] = np.clip(q[:, 2], -hz, hz)
            v = q - a
            n = np.linalg.norm(v, axis=1)
            u = _safe_unit(v, n, np.array([1.0, 0.0, 0.0]))
            return n - r, a + u * r, u
        # cylinder
        r, hz = s[0], s[1]
        rho = np.linalg.norm(q[:, :2], axis=1)
        radial = np.zeros_like(q)
        radial[:, :2] = _safe_unit(q[:, :2], rho, np.array([1.0, 0.0]))
        out_r, out_z = rho > r, np.abs(q[:, 2]) > hz
        outside = out_r | out_z
        c = q.copy()
        scale = np.where(out_r, r / np.maximum(rho, 1e-12), 1.0)
        c[:, :2] = q[:, :2] * scale[:, None]
        c[:, 2] = np.clip(q[:, 2], -hz, hz)
        diff = q - c
        dist = np.linalg.norm(diff, axis=1)
        normal = np.zeros_like(q)
        with np.errstate(invalid="ignore", divide="ignore"):
            normal[outside] = diff[outside] / dist[outside, None]
        inside = ~outside
        if np.any(inside):
            d_side = r - rho
            d_cap = hz - np.abs(q[:, 2])
            side = inside & (d_side <= d_cap)
            cap = inside & ~side
            c[side, :2] = radial[side, :2] * r
            dist[side] = -d_side[side]
            normal[side] = radial[side]
            sz = np.where(q[:, 2] >= 0, 1.0, -1.0)
            c[cap, 2] = sz[cap] * hz
            dist[cap] = -d_cap[cap]
            normal[cap] = 0.0
            normal[cap, 2] = sz[cap]
        return dist, c, normal


def _safe_unit(v: np.ndarray, n: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    out = np.empty_like(v)
    ok = n > 1e-12
    out[ok] = v[ok] / n[ok, None]
    out[~ok] = fallback
    return out


@dataclass(frozen=True)
class ObjectGeometry:
    """A scene object as perception sees it: id, class, world pose and primitives."""

    id: str
    object_class: str
    pos: np.ndarray
    quat: np.ndarray  # (w, x, y, z)
    primitives: tuple[Primitive, ...]
    movable: bool = True

    @property
    def R(self) -> np.ndarray:
        return frames.quat_to_matrix(self.quat)

    def to_local(self, p_world: np.ndarray) -> np.ndarray:
        return (np.atleast_2d(p_world) - self.pos) @ self.R

    def to_world(self, p_local: np.ndarray) -> np.ndarray:
        return np.atleast_2d(p_local) @ self.R.T + self.pos

    def bbox_local(self) -> tuple[np.ndarray, np.ndarray]:
        """Centre and half extents of the axis-aligned bounding box in the object frame."""
        lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
        for p in self.primitives:
            ext = np.abs(p.R) @ p.local_half_extent()
            lo = np.minimum(lo, p.pos - ext)
            hi = np.maximum(hi, p.pos + ext)
        return (lo + hi) / 2.0, np.maximum((hi - lo) / 2.0, 1e-6)

    @property
    def diameter(self) -> float:
        return float(2.0 * np.linalg.norm(self.bbox_local()[1]))

    def canonical(self, p_world: np.ndarray) -> np.ndarray:
        c, h = self.bbox_local()
        return (self.to_local(p_world) - c) / h

    def from_canonical(self, c_canon: np.ndarray) -> np.ndarray:
        c, h = self.bbox_local()
        return self.to_world(np.atleast_2d(c_canon) * h + c)

    def signed_distance(self, p_world: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Signed distance of world points to the union of primitives (negative inside), and for
        each point the closest surface point and outward normal (world) of the primitive whose
        surface is nearest."""
        pl = self.to_local(p_world)
        best_abs = np.full(len(pl), np.inf)
        sd = np.full(len(pl), np.inf)
        cp = np.zeros_like(pl)
        nn = np.zeros_like(pl)
        inside_any = np.zeros(len(pl), bool)
        for prim in self.primitives:
            Rp = prim.R
            q = (pl - prim.pos) @ Rp
            d, c, n = prim.signed_distance_local(q)
            inside_any |= d < 0
            better = np.abs(d) < best_abs
            best_abs[better] = np.abs(d[better])
            sd[better] = d[better]
            cp[better] = c[better] @ Rp.T + prim.pos
            nn[better] = n[better] @ Rp.T
        sd = np.where(inside_any, -np.abs(sd), np.abs(sd))
        R = self.R
        return sd, cp @ R.T + self.pos, nn @ R.T

    def sample_surface(self, spacing: float, rng: np.random.Generator | None = None) -> np.ndarray:
        """About one world point per ``spacing``^2 of surface, on every primitive's surface (points
        inside another primitive of the union are dropped)."""
        rng = rng or np.random.default_rng(0)
        out = []
        for prim in self.primitives:
            h = prim.local_half_extent()
            if prim.type == "box":
                area = 8 * (h[0] * h[1] + h[1] * h[2] + h[0] * h[2])
            else:
                area = 4 * np.pi * h[0] * max(h[0], h[2])
            n = int(np.clip(area / spacing ** 2, 20, 20000))
            q = rng.uniform(-1, 1, (n, 3)) * h
            if prim.type == "box":  # push each sample onto a face, faces chosen by area
                w = np.array([h[1] * h[2], h[0] * h[2], h[0] * h[1]])
                k = rng.choice(3, n, p=w / w.sum())
                q[np.arange(n), k] = np.sign(rng.uniform(-1, 1, n)) * h[k]
            else:
                _, q, _ = prim.signed_distance_local(q)
            out.append(q @ prim.R.T + prim.pos)
        pts = self.to_world(np.concatenate(out))
        sd, _, _ = self.signed_distance(pts)
        return pts[sd > -1e-3]

    def project_to_surface(self, p_world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Closest surface point and outward normal (world) for each point."""
        _, c, n = self.signed_distance(p_world)
        return c, n

    def project_to_surface_facing(self, p_world: np.ndarray, toward_world: np.ndarray,
                                  max_detour: float = FACING_MAX_DETOUR) -> tuple[np.ndarray, np.ndarray]:
        """Like :meth:`project_to_surface`, but each point goes to the closest surface whose outward
        normal looks towards its ``toward_world`` point (the limb's elbow or knee), when one is at most
        ``max_detour`` farther than the closest surface of all.

        Why: a limb touches an object from the side its arm or leg is on. A hand point estimated a
        centimetre deep in a basket's 1 cm wall is closest to the wall's inner face; the person held
        the outer one (S1's grab, session 52)."""
        p_world = np.atleast_2d(np.asarray(p_world, float))
        toward_world = np.atleast_2d(np.asarray(toward_world, float))
        c_out, n_out = self.project_to_surface(p_world)
        c_all, n_all = self._surface_candidates(p_world)
        for i in range(len(p_world)):
            d_near = np.linalg.norm(c_out[i] - p_world[i])
            d = np.linalg.norm(c_all[i] - p_world[i], axis=1)
            facing = np.einsum("ij,ij->i", n_all[i], toward_world[i] - c_all[i]) > 0.0
            ok = facing & (d <= d_near + max_detour)
            if ok.any() and not np.dot(n_out[i], toward_world[i] - c_out[i]) > 0.0:
                k = np.flatnonzero(ok)[np.argmin(d[ok])]
                c_out[i], n_out[i] = c_all[i][k], n_all[i][k]
        return c_out, n_out

    def _surface_candidates(self, p_world: np.ndarray) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """Per point: the projections onto every face of each box primitive and the closest point of
        every other primitive (world points and outward normals), those buried in another
        primitive of the union left out."""
        pl = self.to_local(p_world)
        pts, nrm = [], []
        for prim in self.primitives:
            q = (pl - prim.pos) @ prim.R
            if prim.type == "box":
                h = np.asarray(prim.size[:3], float)
                for k in range(3):
                    for sign in (-1.0, 1.0):
                        c = np.clip(q, -h, h)
                        c[:, k] = sign * h[k]
                        n = np.zeros_like(q)
                        n[:, k] = sign
                        pts.append(c @ prim.R.T + prim.pos)
                        nrm.append(n @ prim.R.T)
            else:
                _, c, n = prim.signed_distance_local(q)
                pts.append(c @ prim.R.T + prim.pos)
                nrm.append(n @ prim.R.T)
        P = np.stack(pts, axis=1) @ self.R.T + self.pos      # (N, M, 3) world
        Nn = np.stack(nrm, axis=1) @ self.R.T
        out_p, out_n = [], []
        for i in range(len(p_world)):
            sd, _, _ = self.signed_distance(P[i])
            keep = sd > -1e-6
            out_p.append(P[i][keep])
            out_n.append(Nn[i][keep])
        return out_p, out_n
