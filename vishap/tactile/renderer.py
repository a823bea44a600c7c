"""The tactile sleeve's 1 kHz cycle: contact sample → drive signals (PHSM §2–§3, HAPTEX §II-C, §III-B).

One :meth:`TactileRenderer.step` per servo tick, in the order of a haptic cycle:

    sense (sensor array, features) → classify → predict (feed-forward) → regional control →
    PHSM targets → JND quantiser → allocation (glove / sleeve) → continuity limits → synthesis

and returns a :class:`DriveBlock` holding that tick's samples (10 at the default 10 kHz) for the
glove channel (0–20 Hz), the three regional sleeve actuators and the 24 HAPTEX pins. Everything is
finite and within [−1, 1]; amplitudes move no faster than ``control.amplitude_slew_per_s``.

When a sample carries no pad geometry (``pad_position``/``contact_radius_m``), the patch comes from
:func:`~vishap.tactile.sensor.pad_patch`: a Hertz patch at the fingertip centre, moved to the finger
pad and stretched when the sample's ``finger_dir`` says the finger lies flat; the array's centroid
velocity and local pulse durations are then taken from the surface kinematics: the tangential finger
velocity and the dwell time (patch length / speed) of a surface point under the patch.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from vishap.tactile.allocation import allocate
from vishap.tactile.classifier import ContactClassifier, ContactState
from vishap.tactile.config import SurfaceAttributes, TactileConfig, load_tactile_config
from vishap.tactile.contact import ContactSample
from vishap.tactile.feedforward import ContactPredictor
from vishap.tactile.jnd import JNDQuantiser
from vishap.tactile.phsm import phsm_targets
from vishap.tactile.pins import PinRenderer, nonuniformity_map, weave_tile
from vishap.tactile.regions import RegionController
from vishap.tactile.sensor import FeatureTracker, SensorArray, SensorFrame, pad_patch
from vishap.tactile.synth import Oscillators

__all__ = ["DriveBlock", "TactileRenderer"]

_STATES = list(ContactState)


@dataclass
class DriveBlock:
    """Drive signals for one tick (or, from :meth:`TactileRenderer.render`, a whole sequence)."""

    t0: float
    fs: float
    glove: np.ndarray            # (n,)
    regions: np.ndarray          # (3, n)
    pins: np.ndarray             # (24, n)
    state: ContactState | list = ContactState.NONE
    prearmed: bool | np.ndarray = False
    envelope: float | np.ndarray = 0.0
    extra: dict = field(default_factory=dict)

    @property
    def n(self) -> int:
        return self.glove.shape[-1]


def _slew(cur, target, step):
    return cur + np.minimum(np.maximum(target - cur, -step), step)


def _slew1(cur: float, target: float, step: float) -> float:
    return float(cur + min(max(target - cur, -step), step))


class TactileRenderer:
    """Contact samples in, per-channel drive signals out; state is public for inspection."""

    #: span of recent centroid positions that counts as "in contact" for the regional weights, s
    REGION_MEMORY_S = 0.15

    def __init__(self, config: TactileConfig | None = None, *, surface: str | SurfaceAttributes = "fabric",
                 tile: np.ndarray | None = None, umap: np.ndarray | None = None, seed: int = 0,
                 feedforward: bool | None = None, heading_rad: float = 0.0):
        self.cfg = cfg = config or load_tactile_config()
        self.surface = cfg.surfaces[surface] if isinstance(surface, str) else surface
        rng = np.random.default_rng(seed)
        self.fs = cfg.allocation.sample_rate_hz
        self.tick_s = 1.0 / cfg.pins.contact_rate_hz
        self.array = SensorArray(cfg.sensor)
        self.tracker = FeatureTracker.from_config(cfg, self.array)
        self.classifier = ContactClassifier(cfg.classifier)
        ff = cfg.feedforward if feedforward is None else cfg.feedforward.model_copy(update={"enabled": feedforward})
        self.predictor = ContactPredictor(ff, slip_speed_m_s=cfg.classifier.slip_speed_m_s)
        self.controller = RegionController(cfg)
        self.jnd = JNDQuantiser(cfg.bands)
        if tile is None:
            tile = weave_tile(self.surface.texture_period_m, cfg.pins.tile_grid_m,
                              amplitude_m=cfg.pins.amplitude_ref_m * (0.5 + self.surface.roughness),
                              roughness_rms_m=0.05 * cfg.pins.amplitude_ref_m, rng=rng)
        if umap is None:
            umap = nonuniformity_map(cfg.pins, rng)
        self.pins = PinRenderer(cfg.pins, tile, umap=umap)
        self.heading_rad = heading_rad
        env = phsm_targets(self.surface, 0.0, 0.0, cfg.bands)[1]  # attack/release depend on the surface only
        self.rise_per_s = min(cfg.control.amplitude_slew_per_s, 1.0 / env.attack_s)
        self.fall_per_s = min(cfg.control.amplitude_slew_per_s, 1.0 / env.release_s)
        # one bank: R1–R3, the HAPTEX 40 Hz and 320 Hz carriers, the glove's force-band oscillation
        self.osc = Oscillators(6, self.fs)
        self._freq = np.zeros(6)
        self._freq[3:5] = (cfg.pins.f_low_hz, cfg.pins.f_high_hz)
        self._amp = np.zeros(6)
        self._amp[3:5] = 1.0
        self._phi = np.zeros(6)
        self.reset()

    # ------------------------------------------------------------------------------------------
    def reset(self) -> None:
        for part in (self.tracker, self.classifier, self.predictor, self.controller, self.jnd, self.pins, self.osc):
            part.reset()
        self.osc.amp[3:5] = 1.0  # the two HAPTEX carriers run at unit amplitude; pins scale them
        self.clock = None            # time up to which samples have been produced
        self.state = ContactState.NONE
        self.effective_state = ContactState.NONE
        self.state_since = 0.0
        self.envelope = 0.0          # sleeve envelope (contact gate × state gain), continuity-limited
        self.region_amp = np.zeros(3)
        self.glove_support = 0.0
        self.glove_osc = 0.0
        self._glove_prev = 0.0
        self._glove_lp = 0.0
        self.pin_from = np.zeros((2, self.pins.n_pins))
        self.pin_to = np.zeros((2, self.pins.n_pins))
        self.pin_t = -math.inf
        self.pin_prev = np.zeros((2, self.pins.n_pins))
        self.features = None
        self._phsm_key = None
        self._lo: deque[tuple[float, float]] = deque()  # monotonic queues: sliding min / max of x
        self._hi: deque[tuple[float, float]] = deque()
        self.prearmed = False
        self.trace: list[dict] | None = None

    def record(self, on: bool = True) -> None:
        """Keep the per-tick control values (for :func:`~vishap.tactile.synth.synthesize` replays and plots)."""
        self.trace = [] if on else None

    # ------------------------------------------------------------------------------------------
    def _sense(self, s: ContactSample):
        force = float(s.normal_force_n) if (s.in_contact and np.isfinite(s.normal_force_n)) else 0.0
        if not (np.isfinite(s.position).all() and np.isfinite(s.velocity).all()):
            force = 0.0  # a corrupt sample is treated as no contact
        force = max(force, 0.0)
        centre, radius = pad_patch(force, self.cfg.sensor, s.finger_dir)
        if s.pad_position is not None:
            centre = s.pad_position
        if s.contact_radius_m is not None:
            radius = s.contact_radius_m
        p = self.array.pressure(centre, radius, force)
        f = self.tracker.update(SensorFrame(s.t, p))
        if s.pad_position is None and f.in_contact:
            f.centroid_velocity_m_s = s.velocity[:2].copy()
            speed = s.tangential_speed
            f.pulse_s = 2.0 * float(radius[0]) / speed if speed > 1e-6 else math.inf
        return f, force, centre, radius if force > 0 else np.zeros(2)

    def step(self, sample: ContactSample) -> DriveBlock:
        """Advance one tick (normally 1 ms) and return that tick's drive signals."""
        cfg, t = self.cfg, float(sample.t)
        if not (np.isfinite(sample.position).all() and np.isfinite(sample.velocity).all()):
            sample = ContactSample(t, np.nan_to_num(sample.position), 0.0, np.zeros(3), False)
        if self.clock is not None and t + self.tick_s < self.clock - 0.05:
            self.reset()  # time went back (a replay restarted): start afresh rather than stay silent
        if self.clock is None:
            self.clock = t
        n = int(round((t + self.tick_s - self.clock) * self.fs))
        n = min(max(n, 0), int(0.05 * self.fs))  # catch up after a stall, at most 50 ms at once
        dt = n / self.fs if n else self.tick_s
        t0 = self.clock
        self.clock = t0 + n / self.fs

        feats, force, centre, radius = self._sense(sample)
        self.features = feats
        state = self.classifier.update(feats)
        pred = self.predictor.update(sample, confirmed=state != ContactState.NONE)
        self.prearmed = pred.prearm and state == ContactState.NONE
        eff = state if state != ContactState.NONE else (pred.state if self.prearmed else ContactState.NONE)
        if eff != self.effective_state:
            self.state_since = t
        self.state, self.effective_state = state, eff
        # parameters may change freely while nothing is being output (pre-arming readies them)
        regions = self.controller.update(eff, dt, silent=self.envelope < 1e-3 and not self.region_amp.any())

        speed = sample.tangential_speed
        key = (round(speed * 1e3), round(force * 1e2))  # 1 mm/s, 10 mN: far below one JND
        if key != self._phsm_key:
            self._phsm_key = key
            tg = phsm_targets(self.surface, speed, force, cfg.bands, force_full_n=cfg.allocation.glove_force_full_n)
            self._phsm = ([b.amplitude for b in tg], [b.frequency_hz for b in tg])
        self.jnd.update(*self._phsm)
        x_cm = 100.0 * (feats.centroid_m[0] if feats.in_contact else centre[0])
        span = self._span_update(t, x_cm, feats.in_contact)
        alloc = allocate(eff, force, self.jnd.amplitude, self.jnd.frequency, regions, span,
                         self.surface.roughness, cfg, time_in_state_s=t - self.state_since)

        # continuity limits (§2.4): every amplitude is slew-limited
        # the sleeve envelope rises and falls with the surface's PHSM attack/release, never faster
        # than the continuity limit
        slew = cfg.control.amplitude_slew_per_s * dt
        if state != ContactState.NONE:
            gate = 1.0
        elif self.prearmed:  # start the ramp so that it reaches prearm_level at the predicted contact
            lvl = cfg.feedforward.prearm_level
            gate = max(0.0, lvl - pred.time_to_contact_s * self.rise_per_s)
            gate = max(gate, min(self.envelope, lvl))
        else:
            gate = 0.0
        target = gate * alloc.sleeve_gain
        rate = self.rise_per_s if target > self.envelope else self.fall_per_s
        self.envelope = _slew1(self.envelope, target, rate * dt)
        self.region_amp = _slew(self.region_amp, self.envelope * alloc.region_amp, slew)
        # glove support stays inside its 0–20 Hz band: critically damped 2nd-order low-pass at the band top
        k = 1.0 - math.exp(-2.0 * math.pi * cfg.allocation.glove_band_hz[1] * dt)
        self._glove_lp += k * (alloc.glove_support - self._glove_lp)
        self.glove_support += k * (self._glove_lp - self.glove_support)
        self.glove_osc = _slew1(self.glove_osc, alloc.glove_osc_amp, slew)

        # HAPTEX pins: 1 kHz anti-aliased contact stream, 40 Hz renderer, linear interpolation between updates
        self.pins.push_contact(sample.position[:2], sample.velocity[:2], force)
        if self.pins.due(t):
            a40, a320 = self.pins.update(t, centre, radius, heading_rad=self.heading_rad)
            self.pin_from = self._pin_now(t)
            self.pin_to = np.vstack([a40, a320])
            self.pin_t = t
        pin_amp = self._pin_now(t + dt) * self.envelope

        block = self._synth(n, t0, regions, pin_amp, alloc.glove_osc_hz)
        block.state, block.prearmed, block.envelope = state, self.prearmed, self.envelope
        if self.trace is not None:
            self.trace.append(dict(t=t, n=n, state=state.value, eff=eff.value, prearmed=self.prearmed, envelope=self.envelope,
                                   force=force, region_amp=self.region_amp.copy(), beta=regions.beta_hz.copy(),
                                   phi=regions.phi_rad.copy(), gamma=regions.gamma.copy(), pin_amp=pin_amp.copy(),
                                   glove_support=self.glove_support, glove_osc=self.glove_osc,
                                   glove_hz=alloc.glove_osc_hz, jnd_sent=self.jnd.sent))
        return block

    def _span_update(self, t: float, x: float, in_contact: bool) -> tuple[float, float]:
        """[min, max] of the centroid x over the last ``REGION_MEMORY_S`` (amortised O(1))."""
        lo, hi = self._lo, self._hi
        if not in_contact:
            lo.clear()
            hi.clear()
        while lo and lo[-1][1] >= x:
            lo.pop()
        lo.append((t, x))
        while hi and hi[-1][1] <= x:
            hi.pop()
        hi.append((t, x))
        old = t - self.REGION_MEMORY_S
        while lo[0][0] < old:
            lo.popleft()
        while hi[0][0] < old:
            hi.popleft()
        return lo[0][1], hi[0][1]

    def _pin_now(self, t: float) -> np.ndarray:
        if not np.isfinite(self.pin_t):
            return self.pin_to.copy()
        s = min(1.0, max(0.0, (t - self.pin_t) / self.pins.period_s))
        return self.pin_from + (self.pin_to - self.pin_from) * s

    def _synth(self, n: int, t0: float, regions, pin_amp: np.ndarray, glove_hz: float) -> DriveBlock:
        f, a, ph = self._freq, self._amp, self._phi
        f[:3], f[5] = regions.beta_hz, glove_hz
        a[:3], a[5] = self.region_amp, self.glove_osc
        ph[:3] = regions.phi_rad
        y = self.osc.run(n, f, a, ph)
        reg, car = y[:3], y[3:5]
        r = self.osc._r
        a40 = self.pin_prev[0][:, None] + (pin_amp[0] - self.pin_prev[0])[:, None] * r
        a320 = self.pin_prev[1][:, None] + (pin_amp[1] - self.pin_prev[1])[:, None] * r
        self.pin_prev = pin_amp
        pins = a40 * car[0] + a320 * car[1]
        support = self._glove_prev + (self.glove_support - self._glove_prev) * r
        self._glove_prev = self.glove_support
        glove = support + y[5]
        out = (glove, reg, pins)
        if not math.isfinite(float(glove.sum()) + float(reg.sum()) + float(pins.sum())):  # never NaN/inf to a device
            out = tuple(np.nan_to_num(x, nan=0.0, posinf=0.0, neginf=0.0) for x in out)
        for x in out:
            np.minimum(x, 1.0, out=x)
            np.maximum(x, -1.0, out=x)
        return DriveBlock(t0, self.fs, *out)

    # ------------------------------------------------------------------------------------------
    def render(self, samples, *, record: bool = True) -> DriveBlock:
        """Run :meth:`step` over a sequence and concatenate the blocks."""
        if record:
            self.record(True)
        blocks = [self.step(s) for s in samples]
        if not blocks:
            z = np.zeros(0)
            return DriveBlock(0.0, self.fs, z, np.zeros((3, 0)), np.zeros((self.pins.n_pins, 0)))
        return DriveBlock(
            blocks[0].t0, self.fs,
            np.concatenate([b.glove for b in blocks]),
            np.concatenate([b.regions for b in blocks], axis=1),
            np.concatenate([b.pins for b in blocks], axis=1),
            state=[b.state for b in blocks],
            prearmed=np.array([b.prearmed for b in blocks]),
            envelope=np.array([b.envelope for b in blocks]),
            extra={"trace": self.trace} if record else {},
        )
