"""ph-explorer: explore, model and diagnose the orientation-dependent errors of a PH20/TP20 head.

The core library (campaign data, kinematics, twin, models, diagnosis) never imports viser; the
web app lives in ph_explorer.app on top of it.
"""

import os

# The core works on many small matrices: one BLAS thread per process beats threads that fight
# over the cores (measured on 2 cores under load: a paper-size diagnosis 27 s -> 2.4 s). It only
# takes effect when numpy is not imported yet (the CLI, the app); a user's own setting wins.
for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

from ph_explorer.campaign import Campaign  # noqa: E402
from ph_explorer.errors import InputError  # noqa: E402
from ph_explorer.geometry import DEFAULT_GEOMETRY, Geometry  # noqa: E402
from ph_explorer.kinematics import Touches, campaign_touches, touch_kinematics  # noqa: E402

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
