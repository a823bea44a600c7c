"""Contact-state classification: concentrated / distributed / slip (PHSM §2.4, §3.1–3.4).

The rules, in order (parameters in ``classifier`` of ``tactile.yaml``):

1. no contact — total force below ``min_force_n`` (or no engaged element);
2. slip — centroid speed above ``slip_speed_m_s`` (15 cm/s) *and* local pulses shorter than
   ``slip_pulse_max_s`` (100 ms);
3. distributed — broad area (≥ ``distributed_area_m2``) held, with stable pressure (coefficient of
   variation of the total force ≤ ``stable_force_cv``), for more than ``stable_time_s`` (250 ms), and
   a moderate mean pressure (below ``concentrated_pressure_pa``);
4. concentrated — otherwise: a small area, a broad one not yet stable, or a firm press whose high
   local pressure marks it as concentrated even when its patch is broad.

:func:`classify_features` is the pure rule; :class:`ContactClassifier` adds a short hold so that a
state must persist ``hold_s`` before it is reported (no chattering at a rule's boundary).
:class:`ThresholdClassifier` is the simple peer a user might pick instead: instantaneous thresholds
on area and centroid speed, no stability or pulse test.
"""
from __future__ import annotations

from enum import Enum

from vishap.tactile.config import ClassifierConfig
from vishap.tactile.sensor import ContactFeatures

__all__ = ["ContactState", "classify_features", "ContactClassifier", "ThresholdClassifier"]


class ContactState(str, Enum):
    NONE = "none"
    CONCENTRATED = "concentrated"
    DISTRIBUTED = "distributed"
    SLIP = "slip"


def classify_features(f: ContactFeatures, cfg: ClassifierConfig) -> ContactState:
    """The paper's rules applied to one feature vector."""
    if not f.in_contact or f.total_force_n < cfg.min_force_n:
        return ContactState.NONE
    if f.speed_m_s > cfg.slip_speed_m_s and f.pulse_s < cfg.slip_pulse_max_s:
        return ContactState.SLIP
    if (f.area_m2 >= cfg.distributed_area_m2 and f.broad_for_s >= cfg.stable_time_s
            and f.force_cv <= cfg.stable_force_cv and f.mean_pressure_pa < cfg.concentrated_pressure_pa):
        return ContactState.DISTRIBUTED
    return ContactState.CONCENTRATED


class ContactClassifier:
    """Rule classifier with a hold time; ``state`` is public and inspectable."""

    def __init__(self, cfg: ClassifierConfig):
        self.cfg = cfg
        self.reset()

    def reset(self) -> None:
        self.state = ContactState.NONE
        self.candidate = ContactState.NONE
        self.candidate_since = 0.0

    def update(self, f: ContactFeatures) -> ContactState:
        raw = classify_features(f, self.cfg)
        if raw == self.state:
            self.candidate = raw
            return self.state
        # leaving contact is reported at once (never render texture in the air)
        if raw == ContactState.NONE:
            self.state = self.candidate = raw
            return self.state
        if raw != self.candidate:
            self.candidate, self.candidate_since = raw, f.t
        if f.t - self.candidate_since >= self.cfg.hold_s or self.state == ContactState.NONE:
            self.state = raw
        return self.state


class ThresholdClassifier:
    """Peer: instantaneous thresholds on area and centroid speed (no stability, pulses or hold)."""

    def __init__(self, cfg: ClassifierConfig):
        self.cfg = cfg

    def reset(self) -> None:
        pass

    def update(self, f: ContactFeatures) -> ContactState:
        if not f.in_contact:
            return ContactState.NONE
        if f.speed_m_s > self.cfg.slip_speed_m_s:
            return ContactState.SLIP
        if f.area_m2 >= self.cfg.distributed_area_m2:
            return ContactState.DISTRIBUTED
        return ContactState.CONCENTRATED
