"""The encountered-type device (VisHap §2.3): PHANToM kinematics, gravity model, plant and controller."""
