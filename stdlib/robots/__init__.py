"""Any torque-controlled arm as a real effector: MuJoCo physics and Pinocchio dynamics from one
robot description (model.py; the robots of robots.toml)."""
