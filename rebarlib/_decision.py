"""Decision rules: how a measured value with an uncertainty is judged against a limit
(ISO 14253-1, ILAC-G8:09/2019, JCGM 106:2012). docs/uncertainty.md explains the three rules.

- ``simple``: the measured value against the limit, as the codes are written (GB 50204
  compares the measured deviation with the allowed one). A value just inside a limit may be
  outside it in truth: up to 50 % chance at the limit itself.
- ``guarded``: the limits narrowed by the expanded uncertainty U = k u on each side (a guard
  band w = U): a value is accepted only where it is inside by at least U, so that the chance of
  accepting a value that is out of tolerance is at most about 2.3 % (k = 2, normal error).
- ``shared risk``: the acceptance zone is the tolerance zone (decisions as simple acceptance);
  the parties agree to share the risk that a value near a limit is judged wrongly. It differs
  from ``simple`` in what the report states, not in the verdicts.
- ``proven``: accepted as under simple acceptance; a rejection only where it is proven
  (ISO 14253-1: non-conformity proven where the value lies beyond the limit by at least U). A
  checkpoint beyond its limit by less than U is not settled: its item fails only where it would
  fail with such checkpoints within, and is left open otherwise.

Every checkpoint whose interval ``[deviation - U, deviation + U]`` reaches over a limit is
marked "within, not proven" or "beyond, not proven", under every rule.
"""

from __future__ import annotations

import math

from ._status import BEYOND, BEYOND_NOT_PROVEN, WITHIN, WITHIN_NOT_PROVEN

__all__ = ["DECISION_RULES", "RULE_TEXT", "check_rule", "decide", "decide_size", "risk_summary"]

DECISION_RULES = ("simple", "guarded", "shared risk", "proven")
RULE_TEXT = {
    "simple": "simple acceptance (ILAC-G8 w = 0): the measured value against the limit, as the code is written",
    "guarded": "guarded acceptance (ILAC-G8 w = U): each limit narrowed by the expanded uncertainty U (k = 2)",
    "shared risk": "shared risk (JCGM 106 §8.3.3): the measured value against the limit, the risk of a wrong "
    "decision near a limit shared by agreement",
    "proven": "simple acceptance, rejection only where proven (ISO 14253-1): a value beyond its limit by less than "
    "the expanded uncertainty U (k = 2) leaves its item open",
}
PROVEN = (WITHIN, BEYOND)
WITHIN_NP, BEYOND_NP = WITHIN_NOT_PROVEN, BEYOND_NOT_PROVEN


def check_rule(value, where: str) -> str:
    """The rule named by ``value`` (case, spaces, hyphens and underscores ignored).

    Examples
    --------
    >>> check_rule("Shared_Risk", "x")
    'shared risk'
    """
    from ._checks import RebarInputError

    key = " ".join(str(value).lower().replace("_", " ").replace("-", " ").split())
    key = {"simple acceptance": "simple", "guarded acceptance": "guarded"}.get(key, key)
    if key not in DECISION_RULES:
        raise RebarInputError(f"{where}: decision_rule: expected one of {list(DECISION_RULES)}, got {value!r}")
    return key


def _phi(x: float) -> float:
    return 0.5 * math.erfc(-x / math.sqrt(2.0))


def p_within(deviation: float, minus, plus, u: float) -> float:
    """Probability that the true deviation lies within [-minus, plus], for a normal error of
    standard deviation ``u`` about the measured one.

    Examples
    --------
    >>> round(p_within(3.0, 3.0, 3.0, 1.0), 3)   # on the limit
    0.5
    """
    lo = -math.inf if minus is None else -minus
    hi = math.inf if plus is None else plus
    if not u or u <= 0:
        return 1.0 if lo <= deviation <= hi else 0.0
    return max(0.0, min(1.0, _phi((hi - deviation) / u) - _phi((lo - deviation) / u)))


def guard(rule: str, U) -> float:
    """The guard band w applied to each limit under ``rule``."""
    return float(U) if rule == "guarded" and U is not None and math.isfinite(U) else 0.0


def decide(accepted: bool, deviation: float, minus, plus, U, k: float) -> tuple:
    """``(decision, risk)`` of a judged checkpoint: decision "within" / "beyond" or "..., not
    proven" where ``[deviation - U, deviation + U]`` reaches over a limit; risk = the chance
    that the decision is wrong (accepted but out of tolerance, or rejected but within), for a
    normal error of standard deviation U / k; None without an uncertainty.

    Examples
    --------
    >>> decide(True, 2.5, 3.0, 3.0, 1.0, 2.0)
    ('within, not proven', 0.159)
    >>> decide(True, 0.0, 3.0, 3.0, 1.0, 2.0)
    ('within', 0.0)
    """
    inside = (minus is None or deviation >= -minus - 1e-9) and (plus is None or deviation <= plus + 1e-9)
    if U is None or not math.isfinite(U):
        return ("within" if accepted else "beyond"), None
    straddles = (minus is not None and deviation - U < -minus < deviation + U) or (
        plus is not None and deviation - U < plus < deviation + U
    )
    word = "within" if inside else "beyond"
    decision = f"{word}, not proven" if straddles else word
    p = p_within(deviation, minus, plus, U / k)
    risk = 1.0 - p if accepted else p
    return decision, round(risk, 3)


def decide_size(accepted: bool, inside: bool, confidence, k: float) -> tuple:
    """``(decision, risk)`` of a bar-size checkpoint from the size's confidence (the posterior
    of the size given): not proven where the confidence is below Φ(k) (0.977 for k = 2)."""
    if confidence is None or not math.isfinite(confidence):
        return ("within" if accepted else "beyond"), None
    word = "within" if inside else "beyond"
    sure = confidence >= _phi(k)
    p_in = confidence if inside else 1.0 - confidence
    risk = 1.0 - p_in if accepted else p_in
    return (word if sure else f"{word}, not proven"), round(max(0.0, min(1.0, risk)), 3)


def risk_summary(checkpoints, rule: str, k: float) -> dict:
    """What the rule implied on these checkpoints: counts of "not proven", the expected number
    of false accepts and false rejects (sums of the checkpoints' risks), the largest of each,
    and the rule's worst case in words."""
    acc = rej = 0.0
    worst_a = worst_r = 0.0
    n_np = {WITHIN_NP: 0, BEYOND_NP: 0}
    n_risk = 0
    for rec in checkpoints:
        d, r, st = rec.get("decision"), rec.get("risk"), rec.get("status")
        if d in n_np:
            n_np[d] += 1
        if r is None or (isinstance(r, float) and math.isnan(r)):
            continue
        n_risk += 1
        if rule == "proven" and d == BEYOND_NP and st != "within":
            continue  # not rejected under this rule: left open, no false reject to expect
        if st == "within":
            acc += r
            worst_a = max(worst_a, r)
        else:
            rej += r
            worst_r = max(worst_r, r)
    worst_case = {
        "simple": "a value accepted on the limit has up to 50 % chance of being out of tolerance",
        "shared risk": "a value accepted on the limit has up to 50 % chance of being out of tolerance, "
        "a value rejected just beyond it as much chance of being within (shared)",
        "proven": "a value accepted on the limit has up to 50 % chance of being out of tolerance; a value "
        f"rejected beyond the limit by U has about {100 * (1 - _phi(k)):.1f} % chance of being within; values "
        "beyond by less than U are left open",
        "guarded": f"a value accepted at the guarded limit has about {100 * (1 - _phi(k)):.1f} % chance "
        "of being out of tolerance; values within the limit by less than U are rejected",
    }[rule]
    return {
        "rule": rule,
        "rule_text": RULE_TEXT[rule],
        "k": k,
        "within_not_proven": n_np[WITHIN_NP],
        "beyond_not_proven": n_np[BEYOND_NP],
        "checkpoints_with_u": n_risk,
        "expected_false_accepts": round(acc, 3),
        "expected_false_rejects": round(rej, 3),
        "max_false_accept": round(worst_a, 3),
        "max_false_reject": round(worst_r, 3),
        "worst_case": worst_case,
    }
