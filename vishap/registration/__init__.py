"""Registration (VisHap §2.2, Eq. 3): the rigid transform ``T_robot_cam`` and the calibrations behind it."""
from vishap.registration import camera_robot
from vishap.registration.rigid import RigidTransform, degeneracy, kabsch_umeyama

__all__ = ["RigidTransform", "degeneracy", "kabsch_umeyama", "camera_robot"]
