"""Measurements behind ``vishap bench tactile`` (and the tests that check their logic).

* texture onset on synthetic approaches, reactive vs feed-forward (PHSM §2.4), and false pre-arms
  on near-misses that stop short of the surface;
* classifier accuracy on labelled noisy sequences, this classifier vs the threshold peer;
* JND quantiser savings on a stroke.
"""
from __future__ import annotations

import numpy as np

from vishap.tactile.classifier import ContactClassifier, ContactState, ThresholdClassifier
from vishap.tactile.config import TactileConfig
from vishap.tactile.examples import make_tracker
from vishap.tactile.renderer import TactileRenderer
from vishap.tactile.scenarios import approach, near_miss
from vishap.tactile.sensor import SensorArray
from vishap.tactile.sequences import frames, labelled_sequence

__all__ = ["texture_onset_s", "onset_gain", "false_prearms", "classifier_accuracy"]

LABELS = (ContactState.CONCENTRATED, ContactState.DISTRIBUTED, ContactState.SLIP)


def texture_onset_s(renderer: TactileRenderer, samples, *, level: float = 0.5) -> float:
    """Time at which the sleeve envelope first reaches ``level`` of its in-contact value."""
    renderer.reset()
    env, ts = [], []
    for s in samples:
        renderer.step(s)
        env.append(renderer.envelope)
        ts.append(s.t)
    env = np.asarray(env)
    steady = env[-1]
    hit = np.nonzero(env >= level * steady)[0]
    return float(ts[hit[0]]) if steady > 0 and hit.size else float("nan")


def onset_gain(cfg: TactileConfig, speeds=(0.05, 0.1, 0.15, 0.2, 0.3), decels=(0.0, 0.5, 1.0), *,
               level: float = 0.5) -> dict:
    """Onset (relative to true contact) reactive vs feed-forward over a grid of approaches."""
    ff, re = TactileRenderer(cfg, feedforward=True), TactileRenderer(cfg, feedforward=False)
    rows = []
    for v in speeds:
        for a in decels:
            samples, tc = approach(v, decel_m_s2=a)
            o_ff = texture_onset_s(ff, samples, level=level) - tc
            o_re = texture_onset_s(re, samples, level=level) - tc
            rows.append({"speed_m_s": v, "decel_m_s2": a, "reactive_ms": 1e3 * o_re, "feedforward_ms": 1e3 * o_ff,
                         "gain_ms": 1e3 * (o_re - o_ff)})
    gains = np.array([r["gain_ms"] for r in rows])
    return {"rows": rows, "median_gain_ms": float(np.median(gains)), "min_gain_ms": float(gains.min()),
            "median_reactive_ms": float(np.median([r["reactive_ms"] for r in rows])),
            "median_feedforward_ms": float(np.median([r["feedforward_ms"] for r in rows]))}


def false_prearms(cfg: TactileConfig, speeds=(0.05, 0.1, 0.2, 0.3), stops_m=(0.0005, 0.001, 0.002, 0.003)) -> dict:
    """Near-misses (stop short of the surface): how many trigger a pre-arm, and how strong it gets."""
    r = TactileRenderer(cfg, feedforward=True)
    rows = []
    for v in speeds:
        for h in stops_m:
            r.reset()
            peak = 0.0
            for s in near_miss(v, h):
                r.step(s)
                peak = max(peak, r.envelope)
            rows.append({"speed_m_s": v, "stop_mm": 1e3 * h, "prearms": r.predictor.prearms, "peak_envelope": peak})
    n_false = sum(1 for x in rows if x["prearms"] > 0)
    return {"rows": rows, "near_misses": len(rows), "false_prearms": n_false, "rate": n_false / len(rows),
            "max_peak_envelope": max(x["peak_envelope"] for x in rows)}


def classifier_accuracy(cfg: TactileConfig, *, n_per_class: int = 20, noise_pa: float = 150.0, seed: int = 0) -> dict:
    """Frame accuracy after each rule's decision time, for the rule classifier and the threshold peer."""
    rng = np.random.default_rng(seed)
    array = SensorArray(cfg.sensor)
    ok = {"rules": [], "threshold": []}
    final = {"rules": [], "threshold": []}  # state at each sequence's last frame
    per_class = {lab.value: {"rules": [], "threshold": []} for lab in LABELS}
    for lab in LABELS:
        for _ in range(n_per_class):
            track = labelled_sequence(lab, rng)
            tr = make_tracker(cfg, array)
            ours, peer = ContactClassifier(cfg.classifier), ThresholdClassifier(cfg.classifier)
            for fr in frames(track, array, rng=rng, noise_pa=noise_pa):
                f = tr.update(fr)
                a, b = ours.update(f), peer.update(f)
                if fr.t >= track.label_from_s:
                    for k, v in (("rules", a == lab), ("threshold", b == lab)):
                        ok[k].append(v)
                        per_class[lab.value][k].append(v)
            final["rules"].append(a == lab)
            final["threshold"].append(b == lab)
    return {
        "rules": float(np.mean(ok["rules"])),
        "threshold": float(np.mean(ok["threshold"])),
        "per_class": {c: {k: float(np.mean(v)) for k, v in d.items()} for c, d in per_class.items()},
        "sequence_final_state": {k: float(np.mean(v)) for k, v in final.items()},
        "sequences": len(final["rules"]),
        "frames": len(ok["rules"]),
        "noise_pa": noise_pa,
    }
