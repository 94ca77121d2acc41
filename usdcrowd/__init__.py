"""usdcrowd: crowd scenes described in USD, simulated, filmed and rendered.

Importing the package registers the crowd schemas with USD, so any stage
opened afterwards knows CrowdGroup, CrowdAgentAPI and the rest. Nothing heavy
(renderers, GL) is imported here.
"""

from ._moved import install as _keep_old_module_names
from .schema import register as _register_schemas

__version__ = "0.1.0"

_register_schemas()
_keep_old_module_names()
