"""Selection inside the folds: the held-out gain of the whole diagnosis, choice of the effect included.

The diagnosis chooses an effect (which one, at which joints, alone or combined) by F tests on its data. A
cross-validation that refits that one choice in each fold scores the choice, not the procedure that made
it: the folds' held-out rows took part in choosing, so the gain is optimistic by the selection. Here each
outer fold runs the whole selection again on its training rows alone, fits its own choice there and
predicts its held-out rows with it (the geometry when it chose nothing). The gain of those predictions is
the procedure's; the choices themselves say whether the cause is stable (:func:`fold_agreement`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lasercal.solver.analysis.stats import HeldOut
from lasercal.solver.errors import IdentificationError
from lasercal.solver.formats.session import Session
from lasercal.solver.identify.measurement import residuals

# the agreement rule: a cause is named when all but at most this many fitted outer folds chose it too
AGREE_ALL_BUT = 1


@dataclass(frozen=True)
class FoldChoice:
    """What one outer fold's selection chose from its training rows.

    Attributes
    ----------
    fold : int
    extension : Extension or Combination or None, the fold's choice fitted on its training rows (None:
        the fold found nothing, or could not be fitted)
    p_value : float, the fold's best candidate's Bonferroni-corrected p (1 when it had none)
    failed : str or None, why the fold could not be fitted
    """

    fold: int
    extension: object
    p_value: float
    failed: str | None = None

    @property
    def label(self) -> str:
        """The cause the fold chose: 'joint_compliance at joint 2', 'none', or 'failed'."""
        if self.failed is not None:
            return "failed"
        return "none" if self.extension is None else self.extension.label

    def as_dict(self) -> dict:
        """The record of ``acceptance['fold_choices']``."""
        return {"fold": self.fold, "label": self.label, "p_value": float(f"{self.p_value:.4g}")}


@dataclass(frozen=True)
class NestedHoldout:
    """The outer folds' held-out residuals of the geometry and of each fold's own choice.

    Attributes
    ----------
    geometric, extended : HeldOut, on the same folds (extended: the geometry's residuals where the fold
        chose nothing)
    choices : list of FoldChoice, one per outer fold with held-out rows
    """

    geometric: HeldOut
    extended: HeldOut
    choices: list


def nested_holdout(session: Session, fold: np.ndarray, choose) -> NestedHoldout:
    """Cross-validation of a selection procedure: each fold selects, fits and predicts on its own.

    Parameters
    ----------
    session : Session
    fold : (m,) int array, the outer folds
    choose : callable, train Session -> (geometric Identification, chosen extension fitted on ``train``
        or None, its Identification or None, best corrected p); may raise IdentificationError

    Returns
    -------
    NestedHoldout
    """
    d = 2 if session.measurement == "laser" else 3  # in-plane spot error, or a 3-D point
    r_geo, r_ext = np.full((session.m, d), np.nan), np.full((session.m, d), np.nan)
    failed, choices = {}, []
    for i in range(int(fold.max()) + 1):
        test = fold == i
        if not test.any():
            continue
        try:
            geo, ext, ext_fit, p = choose(session.subset(~test))
        except IdentificationError as e:
            failed[i] = str(e)
            choices.append(FoldChoice(i, None, 1.0, str(e)))
            continue
        held = session.subset(test)
        r_geo[test] = residuals(geo.model, None, held, geo.extra.get("points"))
        fitted = geo if ext is None else ext_fit
        r_ext[test] = residuals(fitted.model, fitted.extension, held, fitted.extra.get("points"))
        choices.append(FoldChoice(i, None if ext is None else ext_fit.extension, p))
    return NestedHoldout(HeldOut(r_geo, fold, failed), HeldOut(r_ext, fold, dict(failed)), choices)


def same_cause(whole, fold) -> bool:
    """Whether a fold's choice holds the whole session's cause: the effect the whole session chose first
    (a combination's first part) at one of its joints at least (its point, for a point offset), with or
    without further terms. Joints joining or leaving beside a shared one, a second effect combined or not,
    are the selection's usual wobble at the margin; a different effect, or the same effect elsewhere, is
    another cause."""
    if whole is None or fold is None:
        return False
    lead = whole.parts[0]
    return any(
        e.effect == lead.effect
        and (e.point == lead.point if lead.point else bool(set(e.joints) & set(lead.joints)))
        for e in fold.parts
    )


def fold_agreement(whole, choices: list) -> dict:
    """The agreement rule: a cause is named only when all but at most one of the fitted outer folds chose
    it too (:func:`same_cause`) -- with 5 folds, 4 of 5.

    Parameters
    ----------
    whole : Extension or Combination or None, the whole session's choice
    choices : list of FoldChoice

    Returns
    -------
    dict: 'folds_agree' (folds whose choice is the same cause), 'folds_same_cause' (folds whose choice
    carries the whole session's label exactly), 'folds_needed', 'folds_agreed' (bool), 'fold_choices'
    (FoldChoice records), 'disagreement' (label -> folds, when not agreed)
    """
    fitted = [c for c in choices if c.failed is None]
    agree = sum(same_cause(whole, c.extension) for c in fitted)
    label = "none" if whole is None else whole.label
    needed = max(len(fitted) - AGREE_ALL_BUT, 1)
    out = {
        "folds_agree": int(agree),
        "folds_same_cause": int(sum(c.label == label for c in fitted)),
        "folds_needed": int(needed),
        "folds_agreed": bool(whole is not None and agree >= needed),
        "fold_choices": [c.as_dict() for c in choices],
    }
    if whole is not None and not out["folds_agreed"]:
        out["disagreement"] = {
            lb: [c.fold for c in fitted if c.label == lb] for lb in dict.fromkeys(c.label for c in fitted)
        }
    return out
