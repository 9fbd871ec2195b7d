"""The MDP families of the paper (App. C), built host-side and registered under their Colosseum names."""

from jaxmdp.families.construction import CommonParams, Family, build_mdp
from jaxmdp.families.deep_sea import deep_sea
from jaxmdp.families.distributions import Beta, PointMass
from jaxmdp.families.frozen_lake import frozen_lake
from jaxmdp.families.river_swim import river_swim
from jaxmdp.families.simple_grid import simple_grid
from jaxmdp.registry import register

__all__ = ["Family", "CommonParams", "build_mdp", "Beta", "PointMass", "BUILTIN_FAMILIES"]

#: Registry name -> builder of the built-in families.
BUILTIN_FAMILIES = {
    "RiverSwim": river_swim,
    "DeepSea": deep_sea,
    "SimpleGrid": simple_grid,
    "FrozenLake": frozen_lake,
}

for _name, _builder in BUILTIN_FAMILIES.items():
    register(_name, _builder, overwrite=True)
