"""What would separate two candidates a campaign cannot tell apart (ph_explorer.diagnosis.separation)."""

from __future__ import annotations

import numpy as np

from ph_explorer.campaign import Campaign
from ph_explorer.diagnosis.separation import separating_measurements, shared_over
from ph_explorer.effects import DEFAULT_CATALOG
from ph_explorer.effects.effect import Effect
from ph_explorer.kinematics import campaign_touches, touch_kinematics


class ForwardOnlyDirection(Effect):
    """Lost motion as a forward scan shows it, whatever the touch order: the same columns as the
    direction effect on a campaign scanned forward, and none of its dependence on the order."""

    id = "forward_only_direction"
    name = "Lost motion frozen to a forward scan"
    teaching = "A test effect."

    def basis(self, touches):
        forward = touch_kinematics(touches.orientations, touches.geometry, touches.n_repetitions)
        return DEFAULT_CATALOG["direction"]().basis(forward)


def forward_campaign() -> Campaign:
    orientations = np.array([[a, b] for a in (15.0, 45.0, 75.0) for b in (-120.0, 0.0, 120.0)])
    return Campaign(orientations, np.zeros((len(orientations), 2, 64)))


def test_a_reversed_scan_separates_lost_motion_from_its_forward_image():
    campaign = forward_campaign()
    direction, frozen = DEFAULT_CATALOG["direction"](), ForwardOnlyDirection()
    # Scanned forward, the two are the same columns: no fit can tell them apart ...
    assert shared_over(direction, frozen, [campaign_touches(campaign)]) > 0.999
    (separated,) = separating_measurements([(direction, frozen)], campaign)
    # ... and scanning the rings again backwards is what separates them.
    assert separated["shared_now"] > 0.999 and "reversed" in separated["measurement"]
    assert separated["shared"] < 0.9


def test_no_measurement_is_named_for_effects_no_measurement_separates():
    campaign = forward_campaign()
    lobing = DEFAULT_CATALOG["lobing"]()
    (separated,) = separating_measurements([(lobing, DEFAULT_CATALOG["lobing"]())], campaign)
    assert separated["measurement"] == "" and separated["shared"] == separated["shared_now"]
