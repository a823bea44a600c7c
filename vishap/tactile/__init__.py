"""The finger-sleeve tactile layer: HAPTEX pin renderer and the PHSM perceptual-band model.

Modules (one idea each): ``config`` (validated ``tactile.yaml``), ``contact`` (``ContactSample``),
``sensor`` (strain-sensor array, features), ``classifier`` (concentrated / distributed / slip),
``phsm`` (attributes → band targets), ``jnd`` (JND quantiser), ``regions`` (Ψ(x, t), presets,
control rules), ``pins`` (HAPTEX 24-pin renderer), ``feedforward`` (pre-arming), ``allocation``
(glove / sleeve), ``synth`` (10 kHz oscillator bank), ``renderer`` (the 1 kHz cycle),
``sequences`` / ``scenarios`` / ``examples`` / ``evaluate`` (synthetic data, worked examples, bench
measurements). See docs/tactile.md.
"""
from vishap.tactile.classifier import ContactClassifier, ContactState, ThresholdClassifier, classify_features
from vishap.tactile.config import TactileConfig, load_tactile_config
from vishap.tactile.contact import ContactSample
from vishap.tactile.jnd import JNDQuantiser
from vishap.tactile.phsm import BandTarget, phsm_targets
from vishap.tactile.pins import PinRenderer
from vishap.tactile.regions import RegionController, RegionSet, psi, target_regions
from vishap.tactile.renderer import DriveBlock, TactileRenderer
from vishap.tactile.sensor import ContactFeatures, FeatureTracker, SensorArray

__all__ = [
    "ContactSample",
    "TactileRenderer",
    "DriveBlock",
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
