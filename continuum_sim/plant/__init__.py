"""Runtime physics MuJoCo does not have: cable path and friction, motors and spindle drive, foam and cutter."""
