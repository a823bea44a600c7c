"""World model (VisHap §2.2): scenes, interaction modes, the nearest object and the device target ``X_d``."""
