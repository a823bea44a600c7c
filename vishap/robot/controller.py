"""Error-space PD control with gravity compensation and an object gain (VisHap §2.3, Eq. 4–9).

Per servo tick, in the robot frame:

* ``e = X_d − X``, ``ė = Ẋ_d − Ẋ`` (Eq. 4), each low-pass filtered by Eq. 5, ``y = a·x/(s + a)``,
  discretised with backward Euler at the servo period ``T``: ``y_t = (aT·x + y_{t−1}) / (1 + aT)``
  (the paper's ``(a·x + y_{t−1}) / (1 + a)`` with ``a`` in units of the period);
* the impedance force ``f = Kp·e_f + Kv·ė_f``;
* ``F = F_GC + Λ_gain·f`` (Eq. 8), with ``F_GC = J⁻ᵀ τ_g`` from Eq. 6–7 and
  ``Λ_robot = R_robot_obj · Λ_obj · R_robot_objᵀ`` (Eq. 9; the paper writes the same similarity
  transform with ``R`` mapping the device frame to the object frame);
* the world's force law (``extra``) is added to ``Λ f``; that part ramps up linearly over ``ramp_s``
  after start (gravity compensation is on from the first tick);
* ``|F|`` is saturated at the peak force (and τ scaled down as a whole where a motor would exceed its
  peak torque), or at the continuous force while a first-order estimate of
  ``|F|²`` (motor heating, time constant ``thermal_tau_s``) exceeds the continuous force squared;
* ``τ = Jᵀ F`` (Eq. 6).

Targets outside the reachable box are clamped to its nearest point and counted; a non-finite
target keeps the last good one; a device outside the box is pushed back by a spring–damper on its
measured position (``n_outside`` counts the ticks); a non-finite external force is ignored, a non-finite joint reading
commands zero torque — each counted. Nothing non-finite or beyond the limits is ever returned.
The hot path (:meth:`Controller.compute`) works on floats with :mod:`math` only.
"""
from __future__ import annotations

import math

import numpy as np

from vishap._core.errors import ConfigError
from vishap.robot.device import DeviceLimits
from vishap.robot.gains import Gains  # (re-exported: the controller's gains type)
from vishap.robot.params import DEFAULT, PhantomParams

__all__ = ["Gains", "Controller", "kalman_velocity_gains", "WORKSPACE_STIFFNESS_N_M", "WORKSPACE_DAMPING_N_S_M"]

#: the soft wall that keeps the device (not only its target) inside the workspace box: it stops the
#: arm within ≈ 5 mm at the demos' 0.4 m/s, and at that speed its force grows by < 0.4 N per tick
#: (the damping fades in over the first WORKSPACE_DAMPING_RAMP_M), so crossing it is no force step
WORKSPACE_STIFFNESS_N_M = 500.0
WORKSPACE_DAMPING_N_S_M = 5.0
WORKSPACE_DAMPING_RAMP_M = 0.005
#: the most the wall's force may change in one tick (N): crossing the box at the travel limiter's
#: 0.6 m/s, the spring and the fading-in damping alone would change it by 0.66 N a tick (issue 16: no
#: step > 0.5 N outside contact); at 0.25 N a tick the arm, coasting out at 0.6 m/s, stops 6.5 mm outside
WORKSPACE_MAX_STEP_N = 0.25


def kalman_velocity_gains(dt: float, bandwidth_hz: float) -> tuple[float, float, float]:
    """``(dt, k_q, k_w)``: steady-state Kalman gains of a constant-velocity model of one joint.

    Angle and rate are estimated from the angle alone (an encoder); the process noise is white
    acceleration. In the continuous limit the steady-state filter is a second-order Butterworth
    observer with ``ω_n = (q_c / r_c)^¼``, so the noise ratio is set from the wanted bandwidth,
    ``q_c = ω_n⁴·r_c`` (r_c = σ²·dt for a sample variance σ², which then cancels from the gains).
    """
    from scipy.linalg import solve_discrete_are

    wn = 2.0 * math.pi * float(bandwidth_hz)
    r = 1.0  # the sample variance: only the ratio to the process noise matters
    qc = wn**4 * r * dt
    F = np.array([[1.0, dt], [0.0, 1.0]])
    H = np.array([[1.0, 0.0]])
    Q = qc * np.array([[dt**3 / 3.0, dt**2 / 2.0], [dt**2 / 2.0, dt]])
    P = solve_discrete_are(F.T, H.T, Q, np.array([[r]]))
    K = P @ H.T / (H @ P @ H.T + r)
    return float(dt), float(K[0, 0]), float(K[1, 0])


class Controller:
    """Filtered error-space PD + gravity compensation + Λ gain + saturation + ramp-up.

    State (public, inspectable): the tip position ``p`` and velocity ``v`` of the last tick (``v`` from
    the Kalman estimator when enabled: the estimate a force law's damping should use), filtered
    errors ``ef``/``edf`` (tuples), the last commanded force
    ``F_cmd``, its parts ``F_gc`` and ``F_pd`` (= ramp·(Λ f + extra)), the heating estimate
    ``heat`` (N²) and counters ``n_target_clamped``, ``n_saturated``, ``n_rejected``, ``n_faults``.
    """

    def __init__(self, params: PhantomParams = DEFAULT, gains: Gains = Gains(), *, limits: DeviceLimits | None = None):
        if not isinstance(gains, Gains):
            raise ConfigError(f"expected a Gains record, got {type(gains).__name__}", field="gains")
        self.params = params
        self.limits = limits if limits is not None else DeviceLimits.from_params(params)
        self.dt = params.dt
        self._l1, self._l2 = params.l1, params.l2
        self._wmin = tuple(float(v) for v in self.limits.workspace_min)
        self._wmax = tuple(float(v) for v in self.limits.workspace_max)
        self._peak = float(self.limits.peak_force_n)
        self._cont = float(self.limits.continuous_force_n)
        self._heat_k = self.dt / params.thermal_tau_s
        self._motor = tuple(float(v) for v in params.motor_peak_torque_nm)
        self.set_gains(gains)
        self.set_gravity(params)
        self.set_lambda(None)
        #: the object-gain scheduler's force ramp (vishap.robot.object_gain), 0…1: the PD and law force
        #: (not gravity compensation) enter with this weight, and the force the controller gave when the
        #: ramp (re)started fades out with the rest (1 − force_scale), so a restart is a blend, never a
        #: step; 1 leaves the controller as it was
        self.force_scale = 1.0
        self.reset()

    # -- configuration ---------------------------------------------------------------------------
    def set_gains(self, gains: Gains) -> None:
        self.gains = gains
        self._kp, self._kv = float(gains.kp), float(gains.kv)
        aT = gains.a * self.dt
        self._k = aT / (1.0 + aT)  # y += k (x − y)  ⇔  y_t = (aT x + y_{t−1}) / (1 + aT)
        self._ramp = float(gains.ramp_s)
        self._kf = kalman_velocity_gains(self.dt, gains.velocity_hz) if gains.velocity_hz > 0 else None
        self._box_n = max(1, int(round(1.0 / (gains.vision_hz * self.dt)))) if gains.vision_hz > 0 else 0

    def set_gravity(self, params: PhantomParams) -> None:
        """Use Eq. 7 with ``params`` (e.g. ``m_a`` adjusted or ``m_tip`` set for an attached object)."""
        self.gravity_params = params
        self._c2, self._c3 = params.gravity_coefficients

    def set_lambda(self, lambda_obj=None, R_robot_obj=None) -> np.ndarray:
        """Set Λ_gain (Eq. 8–9) from the object's gain (diagonal (3,) or (3, 3)) and its rotation.

        ``None`` restores the identity (free motion). Returns Λ in the robot frame.
        If the device limits carry ``max_stiffness_n_m``, the largest eigenvalue is clipped so that
        ``λ·Kp`` stays below it (and ``lambda_clipped`` is set).
        """
        if lambda_obj is None:
            L = np.eye(3)
        else:
            L = np.asarray(lambda_obj, dtype=np.float64)
            L = np.diag(L) if L.shape == (3,) else L
            if L.shape != (3, 3) or not np.all(np.isfinite(L)):
                raise ConfigError(f"expected a finite diagonal (3,) or matrix (3, 3), got {lambda_obj!r}", field="lambda_gain")
            if R_robot_obj is not None:
                R = np.asarray(R_robot_obj, dtype=np.float64).reshape(3, 3)
                L = R @ L @ R.T
        self.lambda_clipped = False
        self._L_src = None
        ms = self.limits.max_stiffness_n_m
        if ms is not None and self._kp > 0:
            lam_max = float(np.max(np.abs(np.linalg.eigvals(L))))
            if lam_max * self._kp > ms:
                L = L * (ms / (lam_max * self._kp))
                self.lambda_clipped = True
        self.lambda_robot = L
        self._L = tuple(float(v) for v in L.ravel())
        self._L_identity = bool(np.array_equal(L, np.eye(3)))
        return L

    def set_lambda_robot(self, L) -> None:
        """Set Λ_gain already in the robot frame (3×3 nested sequence), cheaply, once per tick.

        For the object-gain scheduler's output: unchanged Λ costs one comparison; a Λ whose row sums
        keep ``λ·Kp`` under the stiffness cap skips the eigenvalue check of :meth:`set_lambda`."""
        if L is self._L_src:
            return
        flat = (L[0][0], L[0][1], L[0][2], L[1][0], L[1][1], L[1][2], L[2][0], L[2][1], L[2][2])
        ms = self.limits.max_stiffness_n_m
        bound = max(abs(flat[0]) + abs(flat[1]) + abs(flat[2]), abs(flat[3]) + abs(flat[4]) + abs(flat[5]),
                    abs(flat[6]) + abs(flat[7]) + abs(flat[8]))
        if not all(math.isfinite(v) for v in flat) or (ms is not None and bound * self._kp > ms):
            self.set_lambda(np.array(flat).reshape(3, 3))  # checks and clips (or raises)
        else:
            self.lambda_clipped = False
            self._L = tuple(float(v) for v in flat)
            self._L_identity = self._L == (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
            self.lambda_robot = np.array(self._L).reshape(3, 3)
        self._L_src = L

    @property
    def thermal_headroom(self) -> float:
        """1 with cold motors … 0 when the heating estimate reaches the continuous force squared (from
        there the force is held to the continuous limit)."""
        c2 = self._cont * self._cont
        return max(0.0, 1.0 - self.heat / c2) if c2 > 0.0 else 0.0

    def reset(self, t_start: float | None = None) -> None:
        """Forget filter state and restart the force ramp (at the next tick, or at ``t_start``)."""
        self.ef = (0.0, 0.0, 0.0)
        self.edf = (0.0, 0.0, 0.0)
        self._fresh = True
        self._t0 = t_start
        self.heat = 0.0
        self.F_cmd = (0.0, 0.0, 0.0)
        self.F_gc = (0.0, 0.0, 0.0)
        self.F_pd = (0.0, 0.0, 0.0)
        self._F_from = (0.0, 0.0, 0.0)  # the force held when the force ramp last restarted
        self._scale_prev = 1.0
        self.p = (0.0, 0.0, 0.0)
        self.v = (0.0, 0.0, 0.0)
        self._kq = None  # Kalman state per joint: (q̂1, q̂2, q̂3, ŵ1, ŵ2, ŵ3)
        self._box = None  # boxcar of the target: ring buffer, running sums, index
        self._Fw = None  # the workspace wall's force on the last tick (None: none)
        self.target = None
        self.target_clamped = False
        self.saturated = False
        self.n_target_clamped = 0
        self.n_saturated = 0
        self.n_rejected = 0
        self.n_faults = 0
        self.n_outside = 0

    # -- the 1 kHz hot path ------------------------------------------------------------------------
    def compute(self, t, q1, q2, q3, w1, w2, w3, xd, yd, zd, vxd=0.0, vyd=0.0, vzd=0.0, fx=0.0, fy=0.0, fz=0.0):
        """Motor torques (τ1, τ2, τ3) in N·m for joint state, target (m, m/s) and extra force (N)."""
        isf = math.isfinite
        if not isf(q1 + q2 + q3 + w1 + w2 + w3):
            self.n_faults += 1
            self.F_cmd = (0.0, 0.0, 0.0)
            return 0.0, 0.0, 0.0
        if not isf(xd + yd + zd + vxd + vyd + vzd):
            self.n_rejected += 1
            if self.target is None:
                xd, yd, zd = self.p
            else:
                xd, yd, zd = self.target
            vxd = vyd = vzd = 0.0
        if not isf(fx + fy + fz):
            self.n_rejected += 1
            fx = fy = fz = 0.0
        # workspace clamp of the target (nearest point of the box)
        lo, hi = self._wmin, self._wmax
        clamped = False
        if xd < lo[0]:
            xd, clamped = lo[0], True
        elif xd > hi[0]:
            xd, clamped = hi[0], True
        if yd < lo[1]:
            yd, clamped = lo[1], True
        elif yd > hi[1]:
            yd, clamped = hi[1], True
        if zd < lo[2]:
            zd, clamped = lo[2], True
        elif zd > hi[2]:
            zd, clamped = hi[2], True
        if clamped:
            self.n_target_clamped += 1
        self.target_clamped = clamped
        self.target = (xd, yd, zd)
        if self._box_n > 1:
            xd, yd, zd, vxd, vyd, vzd = self._boxcar(xd, yd, zd, vxd, vyd, vzd)
        kf = self._kf
        if kf is not None:  # Kalman velocity from the joint angles (the device's rates are ignored)
            st = self._kq
            if st is None:
                st = (q1, q2, q3, 0.0, 0.0, 0.0)
            else:
                T, k1, k2 = kf
                a1, a2, a3 = st[0] + T * st[3], st[1] + T * st[4], st[2] + T * st[5]
                r1, r2, r3 = q1 - a1, q2 - a2, q3 - a3
                st = (a1 + k1 * r1, a2 + k1 * r2, a3 + k1 * r3, st[3] + k2 * r1, st[4] + k2 * r2, st[5] + k2 * r3)
            self._kq = st
            w1, w2, w3 = st[3], st[4], st[5]

        # kinematics (Eq. 6): p, J, v = J q̇
        l1, l2 = self._l1, self._l2
        s1, c1 = math.sin(q1), math.cos(q1)
        s2, c2 = math.sin(q2), math.cos(q2)
        s3, c3 = math.sin(q3), math.cos(q3)
        r = l1 * c2 + l2 * s3
        ja, jb, jc, jd = -l1 * s2, l2 * c3, l1 * c2, l2 * s3  # planar block
        px, py, pz = r * c1, r * s1, l1 * s2 - l2 * c3
        self.p = (px, py, pz)
        vr = ja * w2 + jb * w3  # radial velocity
        vt = r * w1  # tangential
        vx, vy, vz = vr * c1 - vt * s1, vr * s1 + vt * c1, jc * w2 + jd * w3
        self.v = (vx, vy, vz)  # the tip velocity the controller uses (Kalman estimate when enabled)

        # Eq. 4–5: filtered errors
        ex, ey, ez = xd - px, yd - py, zd - pz
        edx, edy, edz = vxd - vx, vyd - vy, vzd - vz
        if self._fresh:
            self._fresh = False
            efx, efy, efz = ex, ey, ez
            edfx, edfy, edfz = edx, edy, edz
            if self._t0 is None:
                self._t0 = t
        else:
            k = self._k
            efx, efy, efz = self.ef
            edfx, edfy, edfz = self.edf
            efx += k * (ex - efx)
            efy += k * (ey - efy)
            efz += k * (ez - efz)
            edfx += k * (edx - edfx)
            edfy += k * (edy - edfy)
            edfz += k * (edz - edfz)
        self.ef = (efx, efy, efz)
        self.edf = (edfx, edfy, edfz)
        kp, kv = self._kp, self._kv
        fpx, fpy, fpz = kp * efx + kv * edfx, kp * efy + kv * edfy, kp * efz + kv * edfz
        # Eq. 8–9: Λ f
        if not self._L_identity:
            L = self._L
            fpx, fpy, fpz = (
                L[0] * fpx + L[1] * fpy + L[2] * fpz,
                L[3] * fpx + L[4] * fpy + L[5] * fpz,
                L[6] * fpx + L[7] * fpy + L[8] * fpz,
            )
        # the device itself kept inside the workspace box: a spring–damper on the part of p outside it
        # (acts on the measured position, so a finger or a law pushing the device out meets it too)
        wx = (lo[0] - px if px < lo[0] else (hi[0] - px if px > hi[0] else 0.0))
        wy = (lo[1] - py if py < lo[1] else (hi[1] - py if py > hi[1] else 0.0))
        wz = (lo[2] - pz if pz < lo[2] else (hi[2] - pz if pz > hi[2] else 0.0))
        if wx or wy or wz or self._Fw is not None:
            if wx or wy or wz:
                self.n_outside += 1
            kw, bw, rw = WORKSPACE_STIFFNESS_N_M, WORKSPACE_DAMPING_N_S_M, 1.0 / WORKSPACE_DAMPING_RAMP_M
            # the damping fades in over the first WORKSPACE_DAMPING_RAMP_M outside (the spring starts at zero)
            ax = kw * wx - (bw * min(1.0, abs(wx) * rw) * vx if vx * wx < 0.0 else 0.0)
            ay = kw * wy - (bw * min(1.0, abs(wy) * rw) * vy if vy * wy < 0.0 else 0.0)
            az = kw * wz - (bw * min(1.0, abs(wz) * rw) * vz if vz * wz < 0.0 else 0.0)
            # and the wall's force changes by at most WORKSPACE_MAX_STEP_N a tick, on the way in and out
            ox, oy, oz = self._Fw or (0.0, 0.0, 0.0)
            dx, dy, dz = ax - ox, ay - oy, az - oz
            dn = math.sqrt(dx * dx + dy * dy + dz * dz)
            if dn > WORKSPACE_MAX_STEP_N:
                k = WORKSPACE_MAX_STEP_N / dn
                ax, ay, az = ox + k * dx, oy + k * dy, oz + k * dz
            self._Fw = None if ax == 0.0 and ay == 0.0 and az == 0.0 else (ax, ay, az)
            fpx += ax
            fpy += ay
            fpz += az
        # ramp-up of everything but gravity compensation
        el = t - self._t0
        s = 1.0 if el >= self._ramp else (el / self._ramp if el > 0.0 else 0.0)
        fs = self.force_scale
        if fs < self._scale_prev:  # the ramp restarted: what was commanded fades out as the new force fades in
            self._F_from = self.F_pd
        self._scale_prev = fs
        Fx, Fy, Fz = s * fs * (fpx + fx), s * fs * (fpy + fy), s * fs * (fpz + fz)
        if fs < 1.0:
            w = 1.0 - fs
            hx, hy, hz = self._F_from
            Fx, Fy, Fz = Fx + w * hx, Fy + w * hy, Fz + w * hz
        self.F_pd = (Fx, Fy, Fz)
        # Eq. 6–7: F_GC = J⁻ᵀ τ_g (τ_g1 = 0, so no tangential part)
        det2 = ja * jd - jb * jc
        if det2 > 1e-9 or det2 < -1e-9:
            tg2, tg3 = self._c2 * c2, self._c3 * s3
            fr = (jd * tg2 - jc * tg3) / det2
            gx, gy, gz = fr * c1, fr * s1, (ja * tg3 - jb * tg2) / det2
        else:
            gx = gy = gz = 0.0
        self.F_gc = (gx, gy, gz)
        Fx += gx
        Fy += gy
        Fz += gz
        # limits: peak force, continuous force while hot
        n2 = Fx * Fx + Fy * Fy + Fz * Fz
        if not isf(n2):  # overflow of finite inputs: keep the direction; no direction left: gravity only
            if isf(Fx) and isf(Fy) and isf(Fz):
                m = max(abs(Fx), abs(Fy), abs(Fz))
                Fx, Fy, Fz = Fx / m * 1e3, Fy / m * 1e3, Fz / m * 1e3  # beyond any limit: saturated below
            else:
                self.n_faults += 1
                Fx, Fy, Fz = gx, gy, gz
            n2 = Fx * Fx + Fy * Fy + Fz * Fz
        flim = self._cont if self.heat > self._cont * self._cont else self._peak
        if n2 > flim * flim:
            sc = flim / math.sqrt(n2)
            Fx, Fy, Fz = Fx * sc, Fy * sc, Fz * sc
            n2 = flim * flim
            self.saturated = True
            self.n_saturated += 1
        else:
            self.saturated = False
        self.heat += self._heat_k * (n2 - self.heat)  # heating from the force actually commanded
        # Eq. 6: τ = Jᵀ F  (J = Rz(θ1)·[[0, ja, jb], [r, 0, 0], [0, jc, jd]])
        Fr = Fx * c1 + Fy * s1
        Ft = -Fx * s1 + Fy * c1
        tau1, tau2, tau3 = r * Ft, ja * Fr + jc * Fz, jb * Fr + jd * Fz
        # each motor's peak torque (its amplifier's current limit): scale τ as a whole, so the force
        # keeps its direction rather than being bent by one clipped motor
        m1, m2, m3 = self._motor
        sc = min(1.0, m1 / abs(tau1) if abs(tau1) > m1 else 1.0, m2 / abs(tau2) if abs(tau2) > m2 else 1.0,
                 m3 / abs(tau3) if abs(tau3) > m3 else 1.0)
        if sc < 1.0:
            tau1, tau2, tau3 = tau1 * sc, tau2 * sc, tau3 * sc
            Fx, Fy, Fz = Fx * sc, Fy * sc, Fz * sc
            if not self.saturated:
                self.saturated = True
                self.n_saturated += 1
        if not isf(tau1 + tau2 + tau3):  # only reachable through overflow: keep gravity compensation alone
            self.n_faults += 1
            Fx, Fy, Fz = gx, gy, gz
            Fr = Fx * c1 + Fy * s1
            tau1, tau2, tau3 = 0.0, ja * Fr + jc * Fz, jb * Fr + jd * Fz
        self.F_cmd = (Fx, Fy, Fz)
        return tau1, tau2, tau3

    def _boxcar(self, xd, yd, zd, vxd, vyd, vzd):
        """Mean of the target over the last sample interval (O(1): a ring buffer and running sums)."""
        v = (xd, yd, zd, vxd, vyd, vzd)
        b = self._box
        n = self._box_n
        if b is None:
            self._box = b = [[v] * n, [x * n for x in v], 0]
            return v
        ring, sums, i = b
        old = ring[i]
        ring[i] = v
        b[2] = (i + 1) % n
        sums = [sums[j] + v[j] - old[j] for j in range(6)]
        b[1] = sums
        return tuple(x / n for x in sums)

    # -- convenience -------------------------------------------------------------------------------
    def command(self, t: float, q, qd, X_d, Xd_dot=(0.0, 0.0, 0.0), extra_force_robot=None) -> np.ndarray:
        """Array wrapper of :meth:`compute`: returns τ (3,) in N·m."""
        q = np.asarray(q, dtype=np.float64).reshape(3)
        qd = np.asarray(qd, dtype=np.float64).reshape(3)
        X = np.asarray(X_d, dtype=np.float64).reshape(3)
        V = np.asarray(Xd_dot, dtype=np.float64).reshape(3)
        E = np.zeros(3) if extra_force_robot is None else np.asarray(extra_force_robot, dtype=np.float64).reshape(3)
        return np.array(self.compute(float(t), *q.tolist(), *qd.tolist(), *X.tolist(), *V.tolist(), *E.tolist()))
