"""The MDP families of the paper (App. C), built host-side and registered under their Colosseum names.

Each family lives in its own module (``jaxmdp.mdp_families.river_swim``, ...), which defines the family's dynamics as a
:class:`Family` and declares a builder function of the same name (its public signature and docstring) that
:func:`~jaxmdp.mdp_families.construction.family_builder` turns into the call ``CommonParams -> Family -> build_mdp``;
the builders are registered in :data:`BUILTIN_FAMILIES`.
"""

from jaxmdp.mdp_families import (
    deep_sea,
    frozen_lake,
    minigrid_doorkey,
    minigrid_empty,
    minigrid_rooms,
    river_swim,
    simple_grid,
    taxi,
)
from jaxmdp.mdp_families.construction import CommonParams, Family, build_mdp
from jaxmdp.mdp_families.distributions import Beta, PointMass, RewardParameters
from jaxmdp.registry import register

__all__ = ["Family", "CommonParams", "RewardParameters", "build_mdp", "Beta", "PointMass", "BUILTIN_FAMILIES"]

#: Registry name -> builder of the built-in families (the paper's seven plus MiniGridDoorKey).
BUILTIN_FAMILIES = {
    "RiverSwim": river_swim.river_swim,
    "DeepSea": deep_sea.deep_sea,
    "SimpleGrid": simple_grid.simple_grid,
    "FrozenLake": frozen_lake.frozen_lake,
    "MiniGridEmpty": minigrid_empty.minigrid_empty,
    "MiniGridRooms": minigrid_rooms.minigrid_rooms,
    "Taxi": taxi.taxi,
    "MiniGridDoorKey": minigrid_doorkey.minigrid_doorkey,
}

for _name, _builder in BUILTIN_FAMILIES.items():
    register(_name, _builder, overwrite=True)
