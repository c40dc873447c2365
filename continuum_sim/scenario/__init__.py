"""The sample-removal scenario (SPEC §5, §7, §8): configuration, runner, metrics."""
