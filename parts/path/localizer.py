"""The pose a path is recorded and followed in: from wheel odometry, from GPS, or both fused.

:class:`Localizer` writes ``loc/x, loc/y, loc/angle, loc/std, loc/ok, loc/source`` from

- ``"odometry"``: the odometer's pose ``pos/x, pos/y, pos/angle`` in the frame of the origin pose
  (the start, or the last ``reset_origin`` command: x forward, y left there). Its uncertainty grows
  by LOC_ODOM_DRIFT per metre driven; it is lost when the encoder is stale.
- ``"gps"``: ``gps/x, gps/y`` (x east, y north) minus the origin (the GPS part's origin, or the
  position at the last ``reset_origin``). Between fixes (a few per second) the pose is carried
  along the arc of the course speed and the previous loop's steering command (bicycle model); at
  each fix the position is the fix and the heading is pulled towards the course between the fix
  and the last one at least LOC_GPS_HEADING_DIST behind it (None until the car has moved that far).
  Its uncertainty is ``gps/accuracy``; it is lost at once when the fix is (``gps/ok`` False).
- ``"fused"``: odometry corrected by GPS fixes, in odometry's frame. Each GPS fix is carried into
  that frame by the rotation and offset that best map the fixes onto the fused positions at the
  same times (least squares, Umeyama/Procrustes in 2-D, from running sums); after
  LOC_FUSE_FIT_DIST metres a Kalman filter takes each fix. Per axis its state is odometry's error
  (variance growing by LOC_ODOM_DRIFT per metre driven) and the GPS's own slowly wandering error
  (first-order Gauss-Markov over LOC_GPS_TAU seconds: coloured measurement noise as an augmented
  state, Gelb, Applied Optimal Estimation; Thrun et al., Probabilistic Robotics, ch. 3), so a GPS
  that wanders for seconds does not drag the pose. While the fix is lost the pose runs on
  odometry and ``loc/std`` grows; LOC_MAX_STD makes it lost beyond a bound. The heading is
  odometry's.
"""

from __future__ import annotations

import logging
import math
from collections import deque
from typing import Any, ClassVar

from parts.sensors.odometry import arc_step, wrap_angle

logger = logging.getLogger(__name__)

SOURCES = ("odometry", "gps", "fused")
#: the white (uncorrelated) part of a GPS fix's error, as a fraction of its sigma
GPS_WHITE_FRACTION = 0.1
#: share of the course's difference from the model's heading taken at each GPS fix
HEADING_GAIN = 0.5
#: floor of loc/std, m: no pose is exact
MIN_STD = 0.01


class _OdometryFrame:
    """The odometer's pose seen from an origin pose, and the distance driven since it was set."""

    def __init__(self) -> None:
        self.origin: tuple[float, float, float] | None = None
        self.last: tuple[float, float] | None = None
        self.distance = 0.0

    def reset(self) -> None:
        self.origin = None  # the next pose becomes the origin

    def local(self, x: float, y: float, angle: float) -> tuple[float, float, float, float]:
        """(x, y, heading, metres moved since the last call) in the origin's frame."""
        if self.origin is None:
            self.origin, self.last, self.distance = (x, y, angle), (x, y), 0.0
        x0, y0, h0 = self.origin
        step = math.hypot(x - self.last[0], y - self.last[1]) if self.last is not None else 0.0
        self.last = (x, y)
        self.distance += step
        c, s = math.cos(h0), math.sin(h0)
        dx, dy = x - x0, y - y0
        return dx * c + dy * s, -dx * s + dy * c, wrap_angle(angle - h0), step


class _GpsFrame:
    """GPS fixes minus an origin, carried between fixes by a motion model.

    Between fixes (a few per second) the pose moves along the arc that the course speed and the
    steering command give (bicycle model). At each fix the position is the fix; the heading is
    corrected by HEADING_GAIN of the difference between the course (the direction from the last fix
    at least ``heading_dist`` behind, which is the heading at the middle of that chord) and the
    model's heading at that middle time.
    """

    def __init__(self, heading_dist: float, wheel_base: float, max_steering_angle: float) -> None:
        self.heading_dist = heading_dist
        self.wheel_base, self.max_steering_angle = wheel_base, max_steering_angle
        self.fixes: deque[tuple[float, float, float]] = deque(maxlen=200)  # (time s, x, y)
        self.history: deque[tuple[float, float]] = deque(maxlen=200)  # (time s, model heading)
        self.reset()
        self.origin = (0.0, 0.0)

    def reset(self) -> None:
        self.origin: tuple[float, float] | None = None  # the next fix becomes the origin
        self.fixes.clear()
        self.history.clear()
        self.pose: list[float] | None = None  # x, y, heading (None until the first course)
        self.speed = 0.0  # m/s over ground, from the course

    def step(self, now: float, dt: float, angle: float | None) -> None:
        """Carry the pose ``dt`` seconds along the model's arc (``angle``: steering command)."""
        if self.pose is None:
            return
        ds = self.speed * dt
        turn = ds * math.tan(-(angle or 0.0) * self.max_steering_angle) / self.wheel_base
        self.pose = list(arc_step(*self.pose, ds, turn))
        self.history.append((now, self.pose[2]))

    def fix(self, x: float, y: float, now: float) -> tuple[float, float, bool]:
        """Take a fix: (x, y) in the origin's frame and whether it is a new one."""
        if self.origin is None:
            self.origin = (x, y)
        px, py = x - self.origin[0], y - self.origin[1]
        new = not self.fixes or self.fixes[-1][1:] != (px, py)
        if not new:
            return px, py, False
        self.fixes.append((now, px, py))
        if self.pose is not None:
            self.pose[0], self.pose[1] = px, py
        for t, qx, qy in reversed(self.fixes):
            if math.hypot(px - qx, py - qy) >= self.heading_dist and now > t:
                self.speed = math.hypot(px - qx, py - qy) / (now - t)
                self._course(math.atan2(py - qy, px - qx), 0.5 * (now + t), px, py)
                break
        return px, py, True

    def _course(self, course: float, mid: float, x: float, y: float) -> None:
        if self.pose is None:
            self.pose = [x, y, course]
            return
        then = min(self.history, key=lambda th: abs(th[0] - mid), default=(mid, self.pose[2]))[1]
        self.pose[2] = wrap_angle(self.pose[2] + HEADING_GAIN * wrap_angle(course - then))

    @property
    def heading(self) -> float | None:
        return None if self.pose is None else self.pose[2]


class _FrameFit:
    """Least-squares rotation and offset mapping points ``g`` onto points ``o`` (2-D Umeyama
    without scale), from running sums."""

    def __init__(self) -> None:
        self.n = 0
        self.sg = [0.0, 0.0]
        self.so = [0.0, 0.0]
        self.sgo = [0.0, 0.0, 0.0, 0.0]  # sum g_x o_x, g_x o_y, g_y o_x, g_y o_y
        self.sgg = 0.0

    def add(self, g: tuple[float, float], o: tuple[float, float]) -> None:
        self.n += 1
        for k in (0, 1):
            self.sg[k] += g[k]
            self.so[k] += o[k]
        self.sgo[0] += g[0] * o[0]
        self.sgo[1] += g[0] * o[1]
        self.sgo[2] += g[1] * o[0]
        self.sgo[3] += g[1] * o[1]
        self.sgg += g[0] * g[0] + g[1] * g[1]

    def spread(self) -> float:
        """RMS distance of the ``g`` points from their centroid, metres."""
        if self.n < 2:
            return 0.0
        mx, my = self.sg[0] / self.n, self.sg[1] / self.n
        return math.sqrt(max(0.0, self.sgg / self.n - mx * mx - my * my))

    def transform(self) -> tuple[float, float, float]:
        """(rotation, tx, ty): o ~ R(rotation) g + t."""
        n = self.n
        mg, mo = (self.sg[0] / n, self.sg[1] / n), (self.so[0] / n, self.so[1] / n)
        hxx = self.sgo[0] - n * mg[0] * mo[0]
        hxy = self.sgo[1] - n * mg[0] * mo[1]
        hyx = self.sgo[2] - n * mg[1] * mo[0]
        hyy = self.sgo[3] - n * mg[1] * mo[1]
        rot = math.atan2(hxy - hyx, hxx + hyy)
        c, s = math.cos(rot), math.sin(rot)
        return rot, mo[0] - (c * mg[0] - s * mg[1]), mo[1] - (s * mg[0] + c * mg[1])


class Localizer:
    """Part: the pose from odometry, GPS or both (see the module docstring).

    ``run(...)`` reads the keys of ``INPUTS`` (which depend on ``source``) and the one-shot
    ``path/command`` ("reset_origin" makes the current pose the origin).

    Args:
        source: "odometry", "gps" or "fused" (PATH_LOCALIZER).
        odom_drift: odometry's 1-sigma position error per metre driven (LOC_ODOM_DRIFT).
        dt: seconds per loop (1 / DRIVE_LOOP_HZ).
        gps_heading_dist: metres between the fixes that give the GPS heading (LOC_GPS_HEADING_DIST).
        gps_tau: seconds over which the GPS's error wanders (LOC_GPS_TAU).
        fit_dist: fused: metres driven before GPS fixes correct the pose (LOC_FUSE_FIT_DIST).
        max_std: the pose is lost beyond this 1-sigma uncertainty, metres (LOC_MAX_STD); None = never.
        gps_std: the GPS's 1-sigma error, metres, when it reports no ``gps/accuracy``.
        wheel_base, max_steering_angle: the GPS localiser's motion model between fixes (WHEEL_BASE,
            MAX_STEERING_ANGLE; it reads the previous loop's ``angle``).
    """

    OUTPUTS: ClassVar[tuple[str, ...]] = ("loc/x", "loc/y", "loc/angle", "loc/std", "loc/ok", "loc/source")

    def __init__(self, source: str = "odometry", *, dt: float = 0.05, odom_drift: float = 0.02,
                 gps_heading_dist: float = 0.5, gps_tau: float = 10.0, fit_dist: float = 8.0,
                 max_std: float | None = None, gps_std: float = 2.5, wheel_base: float = 0.26,
                 max_steering_angle: float = 0.436) -> None:
        if source not in SOURCES:
            raise ValueError(f"PATH_LOCALIZER {source!r}: use one of {', '.join(SOURCES)}")
        if not odom_drift > 0 or not gps_heading_dist > 0 or not fit_dist > 0 or not gps_std > 0:
            raise ValueError("LOC_ODOM_DRIFT, LOC_GPS_HEADING_DIST, LOC_FUSE_FIT_DIST must be > 0")
        self.source = source
        self.dt, self.gps_tau, self.time = float(dt), float(gps_tau), 0.0
        self.odom_drift, self.fit_dist, self.max_std, self.gps_std = odom_drift, fit_dist, max_std, gps_std
        self.gps_sigma = gps_std  # the receiver's latest reported accuracy
        self.odometry = _OdometryFrame()
        self.gps = _GpsFrame(gps_heading_dist, wheel_base, max_steering_angle)
        self._reset_fused()

    @property
    def INPUTS(self) -> tuple[str, ...]:  # noqa: N802 - the part protocol's name
        """The sensors' keys of ``source``, then ``path/command`` (its reset origin)."""
        odo = ("pos/x", "pos/y", "pos/angle") if self.source != "gps" else ()
        gps = ("gps/x", "gps/y", "gps/ok", "gps/accuracy") if self.source != "odometry" else ()
        return (*odo, *gps, *self.FEEDBACK, "path/command")

    @property
    def FEEDBACK(self) -> tuple[str, ...]:  # noqa: N802 - the part protocol's name
        """The GPS localiser's motion model reads the steering command of the previous loop."""
        return ("angle",) if self.source == "gps" else ()

    @property
    def OPTIONAL_INPUTS(self) -> tuple[str, ...]:  # noqa: N802 - the part protocol's name
        """The reset command and the receiver's accuracy may have no producer."""
        return tuple(k for k in self.INPUTS if k in ("path/command", "gps/accuracy"))

    @classmethod
    def from_config(cls, cfg: Any, source: str | None = None) -> Localizer:
        """PATH_LOCALIZER (or ``source``) and the LOC_* settings."""
        return cls(source or cfg.PATH_LOCALIZER, dt=1.0 / cfg.DRIVE_LOOP_HZ, odom_drift=cfg.LOC_ODOM_DRIFT,
                   gps_heading_dist=cfg.LOC_GPS_HEADING_DIST, gps_tau=cfg.LOC_GPS_TAU, fit_dist=cfg.LOC_FUSE_FIT_DIST,
                   max_std=cfg.LOC_MAX_STD, wheel_base=cfg.WHEEL_BASE, max_steering_angle=cfg.MAX_STEERING_ANGLE)

    def _reset_fused(self) -> None:
        self.fit = _FrameFit()
        # per axis the state is (e, b): e = fused minus odometry position (odometry's error, m),
        # b = the GPS's slowly wandering error (first-order Gauss-Markov, tau s); the covariance is
        # the same for x and y: [[P_ee, P_eb], [P_eb, P_bb]]
        self.e = [0.0, 0.0]
        self.b = [0.0, 0.0]
        self.p_ee, self.p_eb, self.p_bb = MIN_STD ** 2, 0.0, self.gps_sigma ** 2
        self.fit_ready = False

    def run(self, *values: Any) -> tuple[Any, ...]:
        """(loc/x, loc/y, loc/angle, loc/std, loc/ok, loc/source)."""
        named = dict(zip(self.INPUTS, values, strict=True))
        self.time += self.dt
        if named.get("path/command") == "reset_origin":
            self.odometry.reset()
            self.gps.reset()
            self._reset_fused()
            logger.info("path: origin reset to the car's current pose")
        if self.source == "odometry":
            return self._odometry(named)
        if self.source == "gps":
            return self._gps(named)
        return self._fused(named)

    def _lost(self) -> tuple[Any, ...]:
        return None, None, None, None, False, self.source

    def _result(self, x: float, y: float, heading: float | None, std: float) -> tuple[Any, ...]:
        std = max(MIN_STD, std)
        ok = self.max_std is None or std <= self.max_std
        return x, y, heading, std, ok, self.source

    def _odometry(self, v: dict[str, Any]) -> tuple[Any, ...]:
        if v["pos/x"] is None or v["pos/y"] is None or v["pos/angle"] is None:
            return self._lost()
        x, y, h, _ = self.odometry.local(v["pos/x"], v["pos/y"], v["pos/angle"])
        return self._result(x, y, h, self.odom_drift * self.odometry.distance)

    def _gps_std(self, v: dict[str, Any]) -> float:
        acc = v.get("gps/accuracy")
        return float(acc) if acc is not None and acc > 0 else self.gps_std

    def _gps(self, v: dict[str, Any]) -> tuple[Any, ...]:
        if not v["gps/ok"] or v["gps/x"] is None or v["gps/y"] is None:
            return self._lost()  # honest: no fix, no pose
        self.gps.step(self.time, self.dt, v.get("angle"))
        x, y, _ = self.gps.fix(v["gps/x"], v["gps/y"], self.time)
        if self.gps.pose is not None:
            x, y = self.gps.pose[0], self.gps.pose[1]
        return self._result(x, y, self.gps.heading, self._gps_std(v))

    def _fused(self, v: dict[str, Any]) -> tuple[Any, ...]:
        if v["pos/x"] is None or v["pos/y"] is None or v["pos/angle"] is None:
            return self._lost()  # without odometry the pose cannot be carried between fixes
        ox, oy, h, step = self.odometry.local(v["pos/x"], v["pos/y"], v["pos/angle"])
        if v["gps/ok"]:
            self.gps_sigma = self._gps_std(v)
        self._predict(step)
        if v["gps/ok"] and v["gps/x"] is not None and v["gps/y"] is not None:
            gx, gy, new = self.gps.fix(v["gps/x"], v["gps/y"], self.time)
            if new:
                # pairs with the fused position: once GPS corrects the pose, the frame keeps the
                # relation found while odometry had not drifted yet, and averages the GPS's error
                self.fit.add((gx, gy), (ox + self.e[0], oy + self.e[1]))
                if not self.fit_ready and self.odometry.distance >= self.fit_dist and self.fit.spread() >= 1.0:
                    self.fit_ready = True
                    logger.info("path: GPS frame fitted over %.1f m; GPS fixes now correct the odometry",
                                self.odometry.distance)
                if self.fit_ready:
                    self._update(gx, gy, ox, oy, self.gps_sigma)
        return self._result(ox + self.e[0], oy + self.e[1], h, math.sqrt(self.p_ee))

    def _predict(self, step: float) -> None:
        """Odometry's error grows by odom_drift per metre driven (its sigma linear in distance); the
        GPS's error decays towards its stationary spread over gps_tau seconds."""
        sigma = math.sqrt(self.p_ee)
        self.p_ee = (sigma + self.odom_drift * step) ** 2
        a = math.exp(-self.dt / self.gps_tau)
        self.b = [a * self.b[0], a * self.b[1]]
        self.p_eb *= a
        self.p_bb = a * a * self.p_bb + (1 - a * a) * self.gps_sigma ** 2

    def _update(self, gx: float, gy: float, ox: float, oy: float, gps_std: float) -> None:
        """Kalman update with one GPS fix carried into odometry's frame: the fix minus odometry's
        position measures e + b, plus a white part of GPS_WHITE_FRACTION of the GPS's sigma."""
        rot, tx, ty = self.fit.transform()
        c, s = math.cos(rot), math.sin(rot)
        z = (c * gx - s * gy + tx - ox, s * gx + c * gy + ty - oy)
        r = (GPS_WHITE_FRACTION * gps_std) ** 2
        var = self.p_ee + 2 * self.p_eb + self.p_bb + r
        k_e, k_b = (self.p_ee + self.p_eb) / var, (self.p_eb + self.p_bb) / var
        for axis in (0, 1):
            innovation = z[axis] - self.e[axis] - self.b[axis]
            self.e[axis] += k_e * innovation
            self.b[axis] += k_b * innovation
        p_ee = self.p_ee - k_e * (self.p_ee + self.p_eb)
        p_eb = self.p_eb - k_e * (self.p_eb + self.p_bb)
        p_bb = self.p_bb - k_b * (self.p_eb + self.p_bb)
        self.p_ee, self.p_eb, self.p_bb = max(p_ee, MIN_STD ** 2), p_eb, max(p_bb, 1e-6)
