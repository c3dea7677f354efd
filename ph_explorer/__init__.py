"""ph-explorer: explore, model and diagnose the orientation-dependent errors of a PH20/TP20 head.

The core library (campaign data, kinematics, twin, models, diagnosis) never imports viser; the
web app lives in ph_explorer.app on top of it.
"""

from ph_explorer.campaign import Campaign
from ph_explorer.errors import InputError
from ph_explorer.geometry import DEFAULT_GEOMETRY, Geometry
from ph_explorer.kinematics import Touches, campaign_touches, touch_kinematics

__version__ = "0.1.0"

__all__ = [
    "Campaign",
    "DEFAULT_GEOMETRY",
    "Geometry",
    "InputError",
    "Touches",
    "campaign_touches",
    "touch_kinematics",
    "__version__",
]
