"""World model (VisHap §2.2–2.3): scenes, interaction modes, the nearest object, the device target
``X_d`` held ahead of the finger, and the force laws of Fig. 5 (HAPTEX §II-B for fabric)."""
from vishap.world.force_laws import ButtonClick, FabricFriction, WallSpring, make_law
from vishap.world.modes import Mode, ModeDatabase, default_modes, load_modes
from vishap.world.predictor import FiniteDifference, KalmanPredictor, LastSample, make_predictor
from vishap.world.scene import Scene, SceneObject, available_scenes, load_scene
from vishap.world.world import Interaction, World

__all__ = [
    "Scene",
    "SceneObject",
    "load_scene",
    "available_scenes",
    "Mode",
    "ModeDatabase",
    "default_modes",
    "load_modes",
    "WallSpring",
    "ButtonClick",
    "FabricFriction",
    "make_law",
    "KalmanPredictor",
    "FiniteDifference",
    "LastSample",
    "make_predictor",
    "Interaction",
    "World",
]
