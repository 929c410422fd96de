"""The knob reader's gates: the one-feature thresholds calibrated on validation readings
(``CalibratedThreshold``), how hard a view is for them (``hard_view``, ``view_level``), why a
fit is no knob whatever its score (``not_there``), and the angles a knob's travel allows
(``allowed_angle``, ``allowed_angles``). The method is described in hearth/perception/knobs.py."""

from __future__ import annotations

import math
from typing import Optional

import numpy as np
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.utils.validation import check_is_fitted

from hearth.perception.knob_config import KnobConfig
from hearth.perception.knob_priors import KnobPrior
from hearth.perception.knob_scoring import _wrap


class CalibratedThreshold(BaseEstimator, ClassifierMixin):
    """A one-feature classifier: ``predict(X)`` is X[:, 0] > ``threshold_``. ``fit(X, y)``
    chooses the threshold on validation readings: ``objective="fewest_errors"`` the middle of
    the lowest step of (positives at or under it) + (negatives over it), as far from both
    kinds of error as the validation set allows (down to ``floor`` where no negative lies
    under the positives); ``"no_false_accepts"`` just above the
    highest negative (times ``safety``, and at least ``floor``), so that no negative of the
    validation set passes."""

    def __init__(self, objective: str = "fewest_errors", safety: float = 1.0, floor: float = 0.0):
        self.objective = objective
        self.safety = safety
        self.floor = floor

    def fit(self, X, y):
        x = np.asarray(X, dtype=float).reshape(len(X), -1)[:, 0]
        y = np.asarray(y).astype(bool)
        pos, neg = np.sort(x[y]), np.sort(x[~y])
        if self.objective == "no_false_accepts":
            top = float(neg[-1]) if len(neg) else self.floor
            t = max(self.floor, top * self.safety if top > 0 else top)
        elif self.objective == "fewest_errors":
            cuts = np.unique(np.concatenate([pos, neg]))
            if len(cuts) == 0:
                t = self.floor
            else:
                # the lowest cut at the floor: with no negative under the positives (the
                # relief check took them all) the step runs from the floor to the lowest
                # positive, not to just under it
                low = [self.floor] if self.floor < cuts[0] - 1e-3 else []
                cand = np.concatenate([low, [cuts[0] - 1e-3], (cuts[:-1] + cuts[1:]) / 2,
                                       [cuts[-1] + 1e-3]])
                err = np.searchsorted(pos, cand, side="right") + (len(neg) - np.searchsorted(neg, cand, side="right"))
                best = np.flatnonzero(err == err.min())
                run = best[:np.argmax(np.diff(np.append(best, best[-1] + 2)) > 1) + 1]
                t = float((cand[run[0]] + cand[run[-1]]) / 2)
        else:
            raise ValueError(f"objective must be fewest_errors or no_false_accepts, not {self.objective!r}")
        self.threshold_ = float(t)
        self.classes_ = np.array([0, 1])
        self.n_features_in_ = 1
        self.validation_ = dict(positives=int(len(pos)), negatives=int(len(neg)),
                                positives_passed=int((pos > t).sum()),
                                negatives_passed=int((neg > t).sum()))
        return self

    def decision_function(self, X) -> np.ndarray:
        check_is_fitted(self)
        return np.asarray(X, dtype=float).reshape(len(X), -1)[:, 0] - self.threshold_

    def predict(self, X) -> np.ndarray:
        return (self.decision_function(X) > 0).astype(int)


def not_there(evidence: dict, config: "KnobConfig") -> Optional[str]:
    """Why a reading is no knob in its region whatever its fit (None: it may be one): its
    depth shows less than ``KnobConfig.min_relief`` of the knob's relief (evidence
    ``stands``; a reading without depth has none and is not judged by it), or it stands more than
    ``max_offset_searches`` search radii from where the map puts the knob (``offset``, in
    search radii: a round body's centre follows the depth's tops, and with the knob gone
    it walked to a packed neighbour's)."""
    stands, se = evidence.get("stands"), evidence.get("stands_se") or 0.0
    if stands is not None and stands + config.relief_sigmas * se < config.min_relief:
        return (f"its depth shows {100 * stands:.0f} % (+- {100 * se:.0f}) of a knob's relief, "
                f"needs {100 * config.min_relief:.0f} %")
    if evidence.get("offset") is not None and evidence["offset"] > config.max_offset_searches:
        return (f"the best fit stands {evidence['offset']:.1f} search radii from where the map "
                f"puts it, at most {config.max_offset_searches:.1f}")
    return None


#: A view is *hard* for the state gate when the knob's radius in the image is under
#: HARD_RADIUS_PX or the camera is more than HARD_OFF_AXIS_DEG off its axis.
HARD_RADIUS_PX = 12.0
HARD_OFF_AXIS_DEG = 45.0


#: ... and *very hard* under VERY_HARD_RADIUS_PX or more than VERY_HARD_OFF_AXIS_DEG off.
VERY_HARD_RADIUS_PX = 8.0
VERY_HARD_OFF_AXIS_DEG = 55.0


def hard_view(radius_px: float, off_axis: float) -> bool:
    """Whether a view of a knob (its radius in pixels, degrees off its axis) is a hard one."""
    return radius_px < HARD_RADIUS_PX or off_axis > HARD_OFF_AXIS_DEG


def view_level(radius_px: float, off_axis: float) -> int:
    """How hard a view is for the state gate: 0, 1 (``hard_view``) or 2 (very hard)."""
    if radius_px < VERY_HARD_RADIUS_PX or off_axis > VERY_HARD_OFF_AXIS_DEG:
        return 2
    return int(hard_view(radius_px, off_axis))


def allowed_angle(prior: KnobPrior, angle: float, margin: float = math.radians(15)) -> bool:
    """Whether a knob angle (rad) lies within the knob's travel (``KnobPrior.travel``, widened
    by ``margin``; modulo its period for a symmetric knob)."""
    if prior.travel is None:
        return True
    lo, hi = prior.travel
    period = 2 * math.pi / max(1, prior.symmetry)
    mid, half = (lo + hi) / 2, (hi - lo) / 2 + margin
    d = abs(math.remainder(angle - mid, period))
    return d <= half


def _with_half_turn(alphas: np.ndarray, picks: list, allowed: np.ndarray) -> list:
    """``picks`` (indices of ``alphas``, the best first) and the allowed angle nearest the
    best one's half turn, within 45 degrees, where it is not among them."""
    d = np.where(allowed, np.abs(_wrap(alphas - alphas[picks[0]] - math.pi)), np.inf)
    flip = int(np.argmin(d))
    return picks + [flip] if flip not in picks and d[flip] < math.radians(45) else picks


def allowed_angles(prior: KnobPrior, angles, margin: float = math.radians(15)) -> np.ndarray:
    """``allowed_angle`` of each of ``angles`` (rad), in one go: the same remainders (each
    exact: ``np.fmod``'s, moved into the half period either side by a subtraction that is
    exact too), so the same answers."""
    angles = np.asarray(angles, dtype=float)
    if prior.travel is None:
        return np.ones(angles.shape, bool)
    lo, hi = prior.travel
    period = 2 * math.pi / max(1, prior.symmetry)
    mid, half = (lo + hi) / 2, (hi - lo) / 2 + margin
    r = np.fmod(angles - mid, period)
    r = np.where(r > period / 2, r - period, np.where(r < -period / 2, r + period, r))
    return np.abs(r) <= half


#: Stored readers (joblib files, hearth/worldmodel/model_store.py) name their classes by module:
#: these keep the module they were stored under before the reader was split into modules
#: (hearth.perception.knobs, which still exports them), so a stored model reads alike with this
#: code and earlier code, and neither makes the other retrain.
for _cls in (CalibratedThreshold,):
    _cls.__module__ = "hearth.perception.knobs"
