"""The contract's name of the obstacles: :class:`carmkin.world.obstacles.Obstacle` (the world holds them)."""

from carmkin.world.obstacles import (  # noqa: F401 (the contract's names)
    CARM_ENVIRONMENT_LINKS,
    CARM_EXCLUDED_PAIRS,
    CARM_MOVING_LINKS,
    Obstacle,
    carm_pair_names,
    link_of,
)
