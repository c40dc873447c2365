"""The runtime physics MuJoCo does not have (cable path, cable friction, motors, cutter): compiled kernels and their hooks."""
