"""Effects outside the head's kinematics: thermal drift with time, and the form of the ring."""

from __future__ import annotations

import functools

import numpy as np
from numpy.typing import NDArray

from ph_explorer.effects.effect import Effect, Evidence, Parameter, ball_centre_mm, full_shape, radial_unit
from ph_explorer.errors import InputError
from ph_explorer.kinematics import Touches

SECONDS_PER_HOUR = 3600.0
DRIFT_TIME_CONSTANTS_S = (300.0, 600.0, 1200.0, 1800.0, 3600.0, 7200.0)
DRIFT_CYCLE_PERIODS_S = (600.0, 900.0, 1200.0, 1800.0, 2700.0, 3600.0)
# Plausible magnitudes of thermal growth, from the drift teaching text's 1.15 um per kelvin for
# 50 mm of aluminium (2.3 um/K on a 100 mm head body): a ramp of up to ~2 K/h (4.6 um/h) and a
# warm-up of up to ~2 K (4.6 um), rounded up to 5; the room cycle "+-0.3 K on 100 mm of aluminium
# is +-0.7 um", generous by 1.5x at the top.
DRIFT_RATE_PLAUSIBLE_UM_PER_H = (0.0, 5.0)
DRIFT_STEP_PLAUSIBLE_UM = (0.0, 5.0)
DRIFT_CYCLE_PLAUSIBLE_UM = (0.0, 1.0)
# "a grade-0 20 mm ring has ~0.2 um of form": 1 um admits worse grades, not a damaged gauge.
RING_FORM_PLAUSIBLE_UM = (0.0, 1.0)


class Drift(Effect):
    id = "drift"
    axis = "environment"
    kind = "thermal"
    name = "Thermal drift of the head with time"
    teaching = (
        "The stylus and the head body grow with temperature, alpha L dT: 1.15 um per kelvin for 50 mm of "
        "aluminium. Growth of the stylus moves the ball along the stylus, whose radial share is only "
        "rho / L (0.11 for a 9 mm contact radius at 80 mm); growth of the head body moves the pivot down "
        "(-z), whose radial share is the ring's tilt (sin A0 at most). Temperature follows a steady ramp "
        "(um per hour), an exponential warm-up (step, time constant tau) and/or the room's air-conditioning "
        "cycle (amplitude, period 15-60 min; +-0.3 K on 100 mm of aluminium is +-0.7 um). The circle fit removes "
        "whatever is constant during one ring: only the change within the ~2 minutes of a ring shows, as "
        "a sawtooth-like pattern with all harmonics. Needs touch times t_s; a warm-up hits the first rings "
        "measured and a room cycle differs from one repetition to the next, so no model indexed by the "
        "orientation can predict it: it raises the error against single repetitions."
    )
    parameters = (
        Parameter(
            "stylus_rate_um_per_h",
            "um/h",
            0.0,
            "steady growth of the stylus along its axis",
            plausible=DRIFT_RATE_PLAUSIBLE_UM_PER_H,
        ),
        Parameter("stylus_step_um", "um", 0.0, "total warm-up growth of the stylus along its axis", plausible=DRIFT_STEP_PLAUSIBLE_UM),
        Parameter(
            "stylus_cycle_um",
            "um",
            0.0,
            "amplitude of the stylus growth that follows the room's temperature cycle",
            plausible=DRIFT_CYCLE_PLAUSIBLE_UM,
        ),
        Parameter(
            "head_rate_um_per_h",
            "um/h",
            0.0,
            "steady growth of the head body, moving the pivot down",
            plausible=DRIFT_RATE_PLAUSIBLE_UM_PER_H,
        ),
        Parameter(
            "head_step_um", "um", 0.0, "total warm-up growth of the head body, moving the pivot down", plausible=DRIFT_STEP_PLAUSIBLE_UM
        ),
        Parameter(
            "head_cycle_um",
            "um",
            0.0,
            "amplitude of the head body growth that follows the room's temperature cycle",
            plausible=DRIFT_CYCLE_PLAUSIBLE_UM,
        ),
        Parameter("cycle_phase_deg", "deg", 0.0, "phase of the temperature cycle at t = 0", period=360.0),
        Parameter("tau_s", "s", 1200.0, "time constant of the warm-up"),
        Parameter("cycle_period_s", "s", 1800.0, "period of the room's temperature cycle (air conditioning)"),
    )
    scan = {"tau_s": DRIFT_TIME_CONSTANTS_S, "cycle_period_s": DRIFT_CYCLE_PERIODS_S}
    needs = frozenset({"touch_times"})

    def basis(self, touches: Touches) -> tuple[NDArray[np.float64], list[str]]:
        cols = self._columns(touches, [self.params["tau_s"]], [self.params["cycle_period_s"]])
        names = [f"drift_{part}_{kind}" for part in ("stylus", "head") for kind in ("rate", "step", "cycle_sin", "cycle_cos")]
        return cols, names

    def scan_library(self, touches: Touches) -> tuple[NDArray[np.float64], list[NDArray[np.intp]]]:
        # One ramp, a warm-up per time constant, a cycle per period: 38 columns for the 36 settings' 288.
        grid = self.scan_grid()
        taus = sorted({s["tau_s"] for s in grid})
        periods = sorted({s["cycle_period_s"] for s in grid})
        n = 1 + len(taus) + 2 * len(periods)  # histories per lever
        indices = []
        for setting in grid:
            i, j = taus.index(setting["tau_s"]), periods.index(setting["cycle_period_s"])
            own = [0, 1 + i, 1 + len(taus) + 2 * j, 2 + len(taus) + 2 * j]  # rate, step, cycle_sin, cycle_cos
            indices.append(np.array([lever * n + k for lever in range(2) for k in own], dtype=np.intp))
        return self._columns(touches, taus, periods), indices

    def _columns(self, touches: Touches, taus: list[float], periods: list[float]) -> NDArray[np.float64]:
        """Each lever (stylus, head) times each growth history per unit coefficient: the ramp (per
        hour), a warm-up per time constant, the two quadratures of a cycle per period."""
        if touches.times_s is None:
            raise InputError("the drift effect needs touch times (a t_s column)", column="t_s")
        if not all(value > 0 for value in [*taus, *periods]):
            raise InputError("drift: tau_s and cycle_period_s must be positive", column="tau_s")
        t = touches.times_s
        levers = touches.memo("drift_levers", lambda: _drift_levers(touches))  # the same at every scanned setting

        def histories():  # one at a time: the columns are as large as the campaign, the histories need not be
            yield t / SECONDS_PER_HOUR
            for tau in taus:
                yield 1.0 - np.exp(-t / tau)
            for period in periods:
                yield np.sin(2 * np.pi * t / period)
                yield np.cos(2 * np.pi * t / period)

        count = 1 + len(taus) + 2 * len(periods)
        cols = np.empty(t.shape + (2, count))  # each lever times each history
        for k, history in enumerate(histories()):
            np.multiply(levers, history[..., None], out=cols[..., k])
        return full_shape(cols.reshape(t.shape + (2 * count,)), touches)

    def coefficients(self) -> NDArray[np.float64]:
        p = self.params
        phase = np.radians(p["cycle_phase_deg"])
        # g sin(w t + phi) = g cos(phi) sin(w t) + g sin(phi) cos(w t)
        return np.array(
            [
                p[f"{part}_{kind}"] * factor
                for part in ("stylus", "head")
                for kind, factor in (("rate_um_per_h", 1.0), ("step_um", 1.0), ("cycle_um", np.cos(phase)), ("cycle_um", np.sin(phase)))
            ]
        )

    def from_coefficients(self, coef: NDArray[np.float64]) -> dict[str, float]:
        c = np.asarray(coef, dtype=float)
        stylus_cycle, head_cycle = np.hypot(c[2], c[3]), np.hypot(c[6], c[7])
        # One phase for the room's cycle: from whichever part carries more of it.
        s, k = (c[6], c[7]) if head_cycle >= stylus_cycle else (c[2], c[3])
        return {
            "stylus_rate_um_per_h": float(c[0]),
            "stylus_step_um": float(c[1]),
            "stylus_cycle_um": float(stylus_cycle),
            "head_rate_um_per_h": float(c[4]),
            "head_step_um": float(c[5]),
            "head_cycle_um": float(head_cycle),
            "cycle_phase_deg": float(np.degrees(np.arctan2(k, s)) % 360.0),
            "tau_s": self.params["tau_s"],
            "cycle_period_s": self.params["cycle_period_s"],
        }

    def evidence(self, touches: Touches) -> Evidence:
        return Evidence("time of the touch (s)", touches.times_s)


class RingForm(Effect):
    id = "ring_form"
    axis = "ring"
    kind = "form"
    name = "Form of the reference ring"
    teaching = (
        "The ring is not perfectly round: a grade-0 20 mm ring has ~0.2 um of form, a few harmonics from "
        "2 to 15 UPR falling with order. The form is fixed in the ring's own frame, so it is identical at "
        "every head orientation: the part of every curve that does not depend on the orientation. Any "
        "model learns it; it is not an error of the head and should be subtracted before judging the head."
    )
    parameters = (
        Parameter("form_um", "um", 0.2, "peak-to-valley form of the ring (harmonics upr_min..upr_max)", plausible=RING_FORM_PLAUSIBLE_UM),
        Parameter("shape_seed", "", 1.0, "seed of the (fixed) random phases and weights of the form's harmonics"),
        Parameter("upr_min", "UPR", 2.0, "lowest harmonic of the form"),
        Parameter("upr_max", "UPR", 15.0, "highest harmonic of the form"),
    )

    def _orders(self) -> NDArray[np.float64]:
        lo, hi = int(self.params["upr_min"]), int(self.params["upr_max"])
        if not 2 <= lo <= hi:
            raise InputError("ring_form: need 2 <= upr_min <= upr_max", column="upr_min")
        return np.arange(lo, hi + 1, dtype=float)

    def basis(self, touches: Touches) -> tuple[NDArray[np.float64], list[str]]:
        n = self._orders()
        theta = np.radians(touches.theta_deg)[:, None] * n  # (n_pt, n_h)
        cols = np.empty((touches.theta_deg.size, 2 * n.size))
        cols[:, 0::2] = np.cos(theta)
        cols[:, 1::2] = np.sin(theta)
        names = [f"ring_{trig}{k:g}theta" for k in n for trig in ("cos", "sin")]
        # The same at every ring and repetition: made once per ring, a view over the repetitions
        # (a dense campaign's full array was 260 MB).
        per_ring = np.ascontiguousarray(np.broadcast_to(cols, touches.shape[:1] + (1,) + cols.shape))
        return full_shape(per_ring, touches), names

    def coefficients(self) -> NDArray[np.float64]:
        n = self._orders()
        rng = np.random.default_rng(int(self.params["shape_seed"]))
        amplitude = rng.uniform(0.5, 1.0, n.size) / n  # falling with order
        phase = rng.uniform(0.0, 2.0 * np.pi, n.size)
        coef = np.empty(2 * n.size)
        coef[0::2], coef[1::2] = amplitude * np.cos(phase), amplitude * np.sin(phase)
        return coef * (self.params["form_um"] / _peak_to_valley(coef, n))

    def from_coefficients(self, coef: NDArray[np.float64]) -> dict[str, float]:
        n = self._orders()
        coef = np.asarray(coef, dtype=float)
        out = {"form_um": _peak_to_valley(coef, n)}
        out.update({f"upr_{k:g}_um": float(a) for k, a in zip(n, np.hypot(coef[0::2], coef[1::2]))})
        return out


def _drift_levers(touches: Touches) -> NDArray[np.float64]:
    """What a unit growth of the stylus and of the head does to each touch's reading, (..., 2)."""
    u = radial_unit(touches)
    stylus = ball_centre_mm(touches) / touches.geometry.pivot_to_ball_mm  # unit stylus direction s_k
    # A touch reads -d . u_k: stylus growth d = g s_k, head growth d = g (-z).
    return np.stack([-np.einsum("...i,...i->...", stylus, u), u[..., 2]], axis=-1)


def _peak_to_valley(coef: NDArray[np.float64], orders: NDArray[np.float64], samples: int = 3600) -> float:
    """Peak-to-valley of sum_n c_n cos(n theta) + s_n sin(n theta), on a dense circle."""
    cos, sin = _dense_circle(tuple(float(n) for n in orders), samples)
    return float(np.ptp(cos @ coef[0::2] + sin @ coef[1::2]))


@functools.lru_cache(maxsize=8)
def _dense_circle(orders: tuple[float, ...], samples: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """cos and sin of n theta on the dense circle (samples, orders): a jackknife asks for the same again and again."""
    theta = np.linspace(0.0, 2.0 * np.pi, samples, endpoint=False)[:, None] * np.asarray(orders)
    cos, sin = np.cos(theta), np.sin(theta)
    cos.flags.writeable = sin.flags.writeable = False
    return cos, sin
