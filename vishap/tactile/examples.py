"""The paper's three worked examples run through the sleeve model (PHSM §3.2–3.4).

Each example is a synthetic patch track (:func:`~vishap.tactile.sequences.worked_example`) read by
the sensor array at 1 kHz, turned into features, classified, and answered with the regional
parameters the controller then uses (the state's target after the control rules).
"""
from __future__ import annotations

import math

import numpy as np

from vishap.tactile.classifier import ContactClassifier, ContactState
from vishap.tactile.config import TactileConfig
from vishap.tactile.regions import target_regions
from vishap.tactile.sensor import FeatureTracker, SensorArray
from vishap.tactile.sequences import WORKED_EXAMPLES, frames, worked_example

__all__ = ["PAPER_REPORTS", "make_tracker", "run_worked_examples"]

#: what the paper reports for each example (§3.2–3.4), for side-by-side comparison
PAPER_REPORTS = {
    "concentrated": {"section": "3.2", "centroid_cm": 3.5, "force_n": 0.65, "t_s": 1.2},
    "distributed": {"section": "3.3", "area_cm2": [0.5, 1.6], "engaged": [8, 19], "force_n": [0.65, 0.48],
                    "stable_ms": ">250", "centroid_cm": 5.0},
    "slip": {"section": "3.4", "centroid_cm": [6.5, 3.9], "duration_s": 0.12, "speed_cm_s": 22,
             "pulses_ms": "<100"},
}


def make_tracker(cfg: TactileConfig, array: SensorArray | None = None) -> FeatureTracker:
    """Shorthand for :meth:`FeatureTracker.from_config`."""
    return FeatureTracker.from_config(cfg, array)


def _r(x, n=3):
    return float(round(float(x), n))


def run_worked_examples(cfg: TactileConfig, *, seed: int = 0, noise_pa: float | None = None) -> dict:
    """Classify the three worked examples; return a JSON-ready record."""
    rng = np.random.default_rng(seed)
    array = SensorArray(cfg.sensor)
    out = {}
    for name in WORKED_EXAMPLES:
        track = worked_example(name)
        tracker, clf = make_tracker(cfg, array), ContactClassifier(cfg.classifier)
        first = None
        feats = []
        for fr in frames(track, array, rng=rng, noise_pa=noise_pa):
            f = tracker.update(fr)
            state = clf.update(f)
            feats.append(f)
            if f.in_contact and first is None:
                first = f
        f = feats[-1]
        cx = [ff.centroid_m[0] for ff in feats if ff.in_contact]
        out[name] = {
            "expected": name,
            "state": state.value,
            "correct": state.value == name,
            "t_s": _r(f.t),
            "measured": {
                "centroid_cm": [_r(100 * cx[0], 2), _r(100 * cx[-1], 2)],
                "area_cm2": [_r(1e4 * (first.area_m2 if first else 0.0), 2), _r(1e4 * f.area_m2, 2)],
                "engaged": [int(first.engaged if first else 0), int(f.engaged)],
                "force_n": _r(f.total_force_n),
                "speed_cm_s": _r(100 * f.speed_m_s, 1),
                "peak_speed_cm_s": _r(100 * max(ff.speed_m_s for ff in feats), 1),
                "pulse_ms": _r(1e3 * f.pulse_s, 1),
                "force_cv": _r(f.force_cv),
                "broad_for_ms": _r(1e3 * f.broad_for_s, 1),
            },
            "paper": PAPER_REPORTS[name],
            "regions": [
                {k: (_r(v, 4) if isinstance(v, float) else v) for k, v in r.items()}
                for r in target_regions(ContactState(state.value), cfg).as_dict()
            ],
        }
    out["all_correct"] = all(out[n]["correct"] for n in WORKED_EXAMPLES)
    out["phase_unit"] = f"rad (pi = {math.pi:.6f})"
    return out
