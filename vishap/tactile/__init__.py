"""The finger-sleeve tactile layer: HAPTEX pin renderer and the PHSM perceptual-band model.

Modules (one idea each): ``config`` (validated ``tactile.yaml``), ``contact`` (``ContactSample``),
``sensor`` (strain-sensor array, features), ``classifier`` (concentrated / distributed / slip),
``phsm`` (attributes → band targets), ``jnd`` (JND quantiser), ``regions`` (Ψ(x, t), presets,
control rules), ``pins`` (HAPTEX 24-pin renderer), ``sequences`` / ``examples`` (synthetic data,
the paper's worked examples).
"""
from vishap.tactile.classifier import ContactClassifier, ContactState, ThresholdClassifier, classify_features
from vishap.tactile.config import TactileConfig, load_tactile_config
from vishap.tactile.contact import ContactSample
from vishap.tactile.jnd import JNDQuantiser
from vishap.tactile.phsm import BandTarget, phsm_targets
from vishap.tactile.pins import PinRenderer
from vishap.tactile.regions import RegionController, RegionSet, psi, target_regions
from vishap.tactile.sensor import ContactFeatures, FeatureTracker, SensorArray

__all__ = [
    "ContactSample",
    "TactileConfig",
    "load_tactile_config",
    "SensorArray",
    "FeatureTracker",
    "ContactFeatures",
    "ContactState",
    "ContactClassifier",
    "ThresholdClassifier",
    "classify_features",
    "BandTarget",
    "phsm_targets",
    "JNDQuantiser",
    "RegionSet",
    "RegionController",
    "psi",
    "target_regions",
    "PinRenderer",
]
