"""The sampling plan and the rig kinematics, with the same conventions as goniowatch's
`measure::plan` and `measure::kinematics` (see ARCHITECTURE.md, "Rig kinematics"):

- lamp fixed at L = (1, 0, 0); camera at C(w) = (cos w, sin w, 0) for wagon angle w;
- arm orientation R = Rz(q1) Ry(q2) Rz(q3), sample -> world; wi = R^T L, wo = R^T C;
- reading = sign * ideal + offset for every joint and the wagon;
- plan entries closer than min_separation_deg are taken at a substitute theta_i on the same
  meridian, at exactly the minimum separation, nearest to the planned theta_i.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

UBO_THETAS = [0.0, 15.0, 30.0, 45.0, 60.0, 75.0]
UBO_DPHI = [0.0, 60.0, 30.0, 20.0, 18.0, 15.0]
HORIZON_EPS = 1e-9


@dataclass
class Plan:
    thetas_deg: list[float] = field(default_factory=lambda: list(UBO_THETAS))
    delta_phi_deg: list[float] = field(default_factory=lambda: list(UBO_DPHI))
    order: str = "light-outer"

    def __post_init__(self) -> None:
        if len(self.thetas_deg) != len(self.delta_phi_deg):
            raise ValueError("plan.thetas_deg and plan.delta_phi_deg differ in length")
        if self.order not in ("light-outer", "camera-outer", "light-outer-serpentine"):
            raise ValueError(f"plan.order: unknown order {self.order!r}")
        self.directions: list[tuple[float, float]] = []
        for t, dp in zip(self.thetas_deg, self.delta_phi_deg):
            if t == 0:
                self.directions.append((0.0, 0.0))
                continue
            steps = 360.0 / dp
            if abs(steps - round(steps)) > 1e-9:
                raise ValueError(f"plan.delta_phi_deg {dp} does not divide 360")
            self.directions.extend((float(t), dp * k) for k in range(int(round(steps))))

    @property
    def n(self) -> int:
        return len(self.directions)

    @property
    def captures(self) -> int:
        return self.n * self.n

    def entry(self, index: int) -> tuple[int, int]:
        """(light, camera) direction indices of capture `index`."""
        n = self.n
        if not 0 <= index < n * n:
            raise IndexError(index)
        outer, inner = divmod(index, n)
        if self.order == "light-outer":
            return outer, inner
        if self.order == "camera-outer":
            return inner, outer
        return outer, (inner if outer % 2 == 0 else n - 1 - inner)

    def index_of(self, light: int, camera: int) -> int:
        n = self.n
        if self.order == "light-outer":
            return light * n + camera
        if self.order == "camera-outer":
            return camera * n + light
        return light * n + (camera if light % 2 == 0 else n - 1 - camera)


def sph_to_vec(theta_deg: float, phi_deg: float) -> np.ndarray:
    t, p = math.radians(theta_deg), math.radians(phi_deg)
    return np.array([math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)])


def vec_to_sph(v: np.ndarray) -> tuple[float, float]:
    rho = math.hypot(v[0], v[1])
    theta = math.degrees(math.atan2(rho, v[2]))
    n = float(np.linalg.norm(v))
    phi = 0.0 if n == 0 or rho <= 1e-12 * n else math.degrees(math.atan2(v[1], v[0])) % 360.0
    return theta, phi


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a × b of two 3-vectors: numpy's own formula, without its axis handling (which costs more
    than the product on one pair)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def angle_between(a: np.ndarray, b: np.ndarray) -> float:
    return math.degrees(math.atan2(float(np.linalg.norm(cross(a, b))), float(np.dot(a, b))))


def rz(a: float) -> np.ndarray:
    s, c = math.sin(a), math.cos(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def ry(a: float) -> np.ndarray:
    s, c = math.sin(a), math.cos(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def zyz(r: np.ndarray) -> tuple[float, float, float]:
    sb = math.hypot(r[0, 2], r[1, 2])
    b = math.atan2(sb, r[2, 2])
    if sb > 1e-12:
        return math.atan2(r[1, 2], r[0, 2]), b, math.atan2(r[2, 1], -r[2, 0])
    if r[2, 2] > 0:
        return math.atan2(r[1, 0], r[0, 0]), b, 0.0
    return math.atan2(-r[1, 0], -r[0, 0]), b, 0.0


def wrap_pm180(a: float) -> float:
    r = (a + 180.0) % 360.0 - 180.0
    return 180.0 if r == -180.0 else r


@dataclass
class Axis:
    offset_deg: float = 0.0
    sign: float = 1.0


@dataclass
class Rig:
    min_separation_deg: float = 12.0
    max_substitute_theta_deg: float = 85.0
    wagon_max_deg: float = 180.0
    joints: list[Axis] = field(default_factory=lambda: [Axis(), Axis(), Axis()])
    wagon: Axis = field(default_factory=Axis)

    @staticmethod
    def from_dict(d: dict) -> "Rig":
        known = {"min_separation_deg", "max_substitute_theta_deg", "wagon_max_deg", "joints", "wagon"}
        unknown = set(d) - known
        if unknown:
            raise ValueError(f"rig: unknown field(s) {sorted(unknown)}")
        joints = [Axis(**j) for j in d.get("joints", [{}, {}, {}])]
        if len(joints) != 3:
            raise ValueError("rig.joints needs three entries")
        return Rig(
            min_separation_deg=float(d.get("min_separation_deg", 12.0)),
            max_substitute_theta_deg=float(d.get("max_substitute_theta_deg", 85.0)),
            wagon_max_deg=float(d.get("wagon_max_deg", 180.0)),
            joints=joints,
            wagon=Axis(**d.get("wagon", {})),
        )

    # forward: readings (q1, q2, q3, w) in degrees -> (wi, wo) in the sample frame
    def forward(self, pose: list[float]) -> tuple[np.ndarray, np.ndarray]:
        q = [math.radians((pose[k] - self.joints[k].offset_deg) * self.joints[k].sign) for k in range(3)]
        w = math.radians((pose[3] - self.wagon.offset_deg) * self.wagon.sign)
        r = rz(q[0]) @ ry(q[1]) @ rz(q[2])
        lamp = np.array([1.0, 0.0, 0.0])
        cam = np.array([math.cos(w), math.sin(w), 0.0])
        return r.T @ lamp, r.T @ cam

    def inverse(self, wi: np.ndarray, wo: np.ndarray) -> list[float]:
        wi = wi / np.linalg.norm(wi)
        wo = wo / np.linalg.norm(wo)
        if wi[2] <= HORIZON_EPS or wo[2] <= HORIZON_EPS:
            raise ValueError("direction at or below the horizon")
        sep = angle_between(wi, wo)
        if sep < self.min_separation_deg - 1e-9 or sep < 1e-9:
            raise OcclusionError(sep)
        wo_perp = wo - wi * np.dot(wi, wo)
        wo_perp /= np.linalg.norm(wo_perp)
        s = np.column_stack([wi, wo_perp, cross(wi, wo_perp)])
        lamp = np.array([1.0, 0.0, 0.0])
        sr = math.radians(sep)
        cam = np.array([math.cos(sr), math.sin(sr), 0.0])
        c_perp = cam - lamp * np.dot(lamp, cam)
        c_perp /= np.linalg.norm(c_perp)
        w = np.column_stack([lamp, c_perp, cross(lamp, c_perp)])
        a, b, c = zyz(w @ s.T)
        ideal = [math.degrees(a), math.degrees(b), math.degrees(c)]
        joints = [wrap_pm180(ideal[k] * self.joints[k].sign + self.joints[k].offset_deg) for k in range(3)]
        return joints + [sep * self.wagon.sign + self.wagon.offset_deg]

    def substitute_theta_i(self, ti: float, pi: float, to: float, po: float) -> float:
        gmin = math.radians(self.min_separation_deg) + 1e-9
        a = math.cos(math.radians(to))
        b = math.sin(math.radians(to)) * math.cos(math.radians(pi - po))
        r = math.hypot(a, b)
        delta = math.atan2(b, a)
        ratio = math.cos(gmin) / r
        if ratio > 1.0:
            return ti
        off = math.acos(max(-1.0, min(1.0, ratio)))
        tmax = math.radians(self.max_substitute_theta_deg)
        t0 = math.radians(ti)
        best = None
        for cand in (delta - off, delta + off):
            if 0.0 <= cand <= tmax:
                if best is None or abs(cand - t0) < abs(best - t0) - 1e-12 or (
                    abs(abs(cand - t0) - abs(best - t0)) <= 1e-12 and cand < best
                ):
                    best = cand
        if best is None:
            raise ValueError("no substitute theta_i")
        return math.degrees(best)

    def plan_pose(self, light: tuple[float, float], camera: tuple[float, float]):
        """(pose readings, used wi, used wo, substitute theta_i or None)."""
        wi = sph_to_vec(*light)
        wo = sph_to_vec(*camera)
        try:
            return self.inverse(wi, wo), wi, wo, None
        except OcclusionError:
            t = self.substitute_theta_i(light[0], light[1], camera[0], camera[1])
            wi2 = sph_to_vec(t, light[1])
            return self.inverse(wi2, wo), wi2, wo, t


class OcclusionError(ValueError):
    def __init__(self, sep: float) -> None:
        super().__init__(f"lamp-camera separation {sep:.3f} deg below the minimum")
        self.separation = sep
