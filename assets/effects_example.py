"""An example of a user-defined effect for ph-explorer: the form error of the stylus ball.

Use it with `ph-explorer diagnose --data CAMPAIGN.csv --effects effects_example.py`, or in Python with
`catalog = ph_explorer.effects.DEFAULT_CATALOG.with_file("effects_example.py")`; a scenario read with
that catalog may use `id = "my_ball_form"` in its [[effects]] tables like any built-in effect.

It writes the same mechanism as the built-in `ball_form` (ph_explorer/effects/stylus.py), so that
you can compare the two: copy this file, change the id (an id must not repeat a built-in one: the
catalog refuses the file with one line saying so) and write your own mechanism in `basis`.

An effect is a subclass of ph_explorer.effects.effect.Effect with an id, a name, a teaching text, its
parameters (with units, defaults and, for a magnitude, the plausible range of its size; for a phase,
its period), the values a diagnosis should try for its non-linear
parameters (`scan`), and a linear `basis` at the instance's own values of them; `forward` (the
deviations it adds before the circle fit) defaults to `basis @ coefficients()`. Every array is shaped like the campaign's touches,
(n_orientations, n_repetitions, n_points), with a trailing column axis for the basis.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ph_explorer.effects.effect import Effect, Parameter, full_shape
from ph_explorer.kinematics import Touches


class MyBallForm(Effect):
    id = "my_ball_form"
    name = "Form error of the stylus ball (user example)"
    teaching = (
        "The stylus ball is not a perfect sphere (sphericity 0.08-0.25 um by grade). The wall touches the "
        "ball at the point opposite the probing force, fixed in the probe frame by the force azimuth psi: "
        "a larger local radius makes the wall read closer, a deviation of minus the radius error at that "
        "point. Modelled as one harmonic of psi, `lobes` per turn of the ball."
    )
    parameters = (
        # plausible: the range of |amplitude| a real ball can have ("sphericity 0.08-0.25 um by grade",
        # generous by 1.5x at the top); a fit outside it is reported as implausible, never accepted.
        Parameter("amplitude_um", "um", 0.05, "amplitude of the ball's radius error", plausible=(0.0, 0.4)),
        # period: a phase repeats every 360 deg, so its uncertainty wraps around.
        Parameter("phase_deg", "deg", 0.0, "azimuth of the first high point in the probe frame, times lobes", period=360.0),
        Parameter("lobes", "UPR", 2.0, "undulations of the ball's radius per turn of psi"),
    )
    scan = {"lobes": (2.0, 3.0, 4.0, 5.0)}

    def basis(self, touches: Touches) -> tuple[NDArray[np.float64], list[str]]:
        k = self.params["lobes"]
        psi = np.radians(touches.psi_deg)  # (n_o, 1, n_pt): the same at every repetition
        columns = -np.stack([np.cos(k * psi), np.sin(k * psi)], axis=-1)
        return full_shape(columns, touches), [f"my_ball_cos{k:g}psi", f"my_ball_sin{k:g}psi"]

    def coefficients(self) -> NDArray[np.float64]:
        phase = np.radians(self.params["phase_deg"])
        return self.params["amplitude_um"] * np.array([np.cos(phase), np.sin(phase)])

    def from_coefficients(self, coef: NDArray[np.float64]) -> dict[str, float]:
        c, s = np.asarray(coef, dtype=float)[:2]
        return {
            "amplitude_um": float(np.hypot(c, s)),
            "phase_deg": float(np.degrees(np.arctan2(s, c)) % 360.0),
            "lobes": self.params["lobes"],
        }
