r"""The diagnosis's verdict as words: one judge, the held-out table.

Every joint is in exactly one of three states after the selected effects (judged on the held-out
data, :func:`consistid.diagnosis.remainder.analyse_remainder`):

* **flagged** — a remainder: held-out RMS above ``REMAINDER_RATIO`` × its floor, relevant and
  significant;
* **undetermined** — the floor cannot be seen there, or the joint is left above the ratio by
  less than the signal chain's own error (or not significantly): neither explained nor a
  remainder;
* **explained** — at most ``REMAINDER_RATIO`` × its floor.

The verdict names every joint of the first two states, in that order, and reads ``"explained"``
only when no joint is in either: ``"remainder on A, B; undetermined on C"``. Naming only the
flagged joints when others are undetermined (as it did) reads as if the others were explained.
"""

from __future__ import annotations

from collections.abc import Sequence


def verdict_head(flagged: Sequence[str], undetermined: Sequence[str]) -> str:
    """``"explained"``, ``"remainder on <joints>"``, ``"undetermined on <joints>"`` or
    ``"remainder on <joints>; undetermined on <joints>"``: every joint not explained, named
    once (``flagged`` and ``undetermined`` are disjoint)."""
    parts = []
    if flagged:
        parts.append(f"remainder on {', '.join(flagged)}")
    if undetermined:
        parts.append(f"undetermined on {', '.join(undetermined)}")
    return "; ".join(parts) or "explained"


def verdict_text(flagged: Sequence[str], undetermined: Sequence[str],
                 why_flagged: str, why_undetermined: str, why_explained: str) -> str:
    """The long verdict: :func:`verdict_head`, a colon, then the reasons of the states it names
    (``why_flagged`` for the remainder, ``why_undetermined`` for the undetermined joints; the
    ``why_explained`` alone when it names none), joined by ``"; "``."""
    head = verdict_head(flagged, undetermined)
    why = [w for named, w in ((flagged, why_flagged), (undetermined, why_undetermined))
           if named and w]
    return f"{head}: {'; '.join(why) if why else why_explained}"
