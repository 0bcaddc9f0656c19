"""The words a diagnose report and a result are shown in, shared by the command line
(:mod:`robocal.cli.diagnose`) and the HTML page (:mod:`robocal.report.page`): a compliance's
correlations, the shapes a joint's error could not be told from and an outlier entry's settling
as plain text, the joint maps as CSV tables, the
units deviations are displayed in."""

from __future__ import annotations

import numpy as np

from ..diagnosis_file import DiagnosisReport


#: deviation display: unit in the file -> (unit shown, factor)
SHOWN = {"mm": ("mm", 1.0), "rad": ("deg", float(np.degrees(1.0))), "1": ("ppm", 1e6)}


def correlation_words(others) -> str:
    """A compliance's correlation with the other compliances (an effect's ``correlation``: how
    well the data split them), as plain text; entries a hand-edited file makes other than numbers
    are left out."""
    if not isinstance(others, dict):
        return ""
    return "".join(f"; correlation with {label} {r:+.2f}" for label, r in others.items() if isinstance(r, (int, float)))


def alike_words(significance) -> str:
    """The shapes of a joint's reading error the data could not tell from the one named (an
    effect's ``significance.undetermined_between``), as plain text; "" for none or a hand-edited
    entry. The claim is "one of these"."""
    alike = significance.get("undetermined_between") if isinstance(significance, dict) else None
    if not isinstance(alike, list) or not alike or not all(isinstance(a, str) for a in alike):
        return ""
    return f"; the data cannot tell it from {', '.join(alike)}"


def settling_words(moves) -> str:
    """Whether an outliers entry's readings follow long joint moves beyond chance (its
    ``after_long_moves``: readings taken before the arm settled), as plain text; "" otherwise or
    for a hand-edited entry."""
    if not isinstance(moves, dict) or not moves.get("settling"):
        return ""
    try:
        return (
            f"; {int(moves['outliers'])} of {int(moves['of'])} follow a joint move of {float(moves['threshold_deg']):g} deg or more "
            f"({float(moves['share_of_samples']):.1%} of all samples do; p = {float(moves['p_value']):.1g}): readings taken before the arm settled"
        )
    except (KeyError, TypeError, ValueError):
        return ""


def map_tables(report: DiagnosisReport) -> list[tuple[str, str]]:
    """``(file name, CSV text)`` of every joint map of a diagnose report: angle, correction and
    its standard deviation in degrees, one row per point of the curve."""
    out = []
    for e in report.effects:
        if e.kind == "joint_map" and e.curve is not None:
            c = e.curve
            rows = zip(c.angle_deg, c.value_deg, c.std_deg if c.std_deg is not None else [float("nan")] * len(c.angle_deg))
            text = "angle_deg,correction_deg,std_deg\n" + "".join(f"{a:.6f},{v:.9g},{sd:.9g}\n" for a, v, sd in rows)
            out.append((f"map_joint{e.joint}.csv", text))
    return out
