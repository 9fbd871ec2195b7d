"""``jaxmdp.agent_interface``: a short name for :mod:`jaxmdp.experiment.agent_interface`, where everything is
defined."""

from jaxmdp.experiment.agent_interface import *  # noqa: F401,F403
from jaxmdp.experiment.agent_interface import __all__  # noqa: F401
