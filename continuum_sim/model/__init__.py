"""Generated MuJoCo model: pure PyMJCF builders from configuration to MJCF (SPEC §6)."""
