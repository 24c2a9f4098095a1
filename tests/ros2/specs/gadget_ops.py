"""The external operation of tests/ros2/specs/wire.rssm."""


def smooth(average: float, sample: float) -> float:
    """An exponential moving average with weight 1/2."""
    return 0.5 * average + 0.5 * sample
