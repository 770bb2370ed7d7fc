"""GAIDE and the neural baselines: point-cloud set abstraction, the graph-masked transformer,
MPNet and SIMPNet, their training data, training loop and checkpoints, and the sampler the
neural bidirectional planner draws from."""

__all__ = [
    "checkpoint",
    "data",
    "data_backends",
    "embodiment",
    "models",
    "pointnet",
    "sampler",
    "train",
]
