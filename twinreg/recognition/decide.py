"""The one decision on an object's model and kind, after the matcher and the kind vote, for build-twin (scene and
city, through :func:`twinreg.stages.recognise`) and ``classify`` alike: a model under the confidence floor is
withdrawn (:func:`apply_floor`); a model decided at the floor or above confirms a kind the object fits but could
not be named (:func:`~twinreg.recognition.kinds.confirmed_by_model`); a model of another kind than the object's,
or a scanned exemplar ``label`` stored, is withdrawn (:func:`apply_kinds`)."""

from __future__ import annotations

from dataclasses import replace

from .kinds import UNKNOWN, References, confirmed_by_model


def decide(outcomes: list, kinds: list, refs: References, floor: float) -> tuple[list, list]:
    """(the outcomes, the kinds) once the floor and the kinds have had their say (see the module's text);
    ``outcomes`` are the matcher's (:class:`~twinreg.matching.match.ObjectOutcome`), ``kinds`` the kind vote's
    (:class:`~twinreg.recognition.kinds.KindResult`), one each per object."""
    category = dict(zip(refs.ids.tolist(), refs.kinds.tolist()))
    outcomes = apply_floor(outcomes, floor)
    kinds = [k if r.match is None or r.match.model_id in refs.exemplars else
             confirmed_by_model(k, category.get(r.match.model_id), r.match.confidence)
             for k, r in zip(kinds, outcomes)]
    return apply_kinds(outcomes, kinds, category, refs.exemplars), kinds


def apply_floor(outcomes: list, floor: float) -> list:
    """The outcomes with every model whose confidence is under ``floor`` withdrawn: ``match`` None, the reason
    code ``under_floor``, the withdrawn model first among the candidates (the scan does not decide it)."""
    out = []
    for res in outcomes:
        m = res.match
        if m is not None and m.confidence is not None and m.confidence < floor:
            others = [c for c in res.candidates if c != m.model_id]
            res = replace(res, match=None, candidates=[m.model_id, *others],
                          reason=f"the best model, {m.name}, has confidence {m.confidence:.2f}, under the floor "
                                 f"{floor:g} (--min-confidence)",
                          reason_code="under_floor", rejected={"name": m.name, "confidence": round(m.confidence, 3)})
        out.append(res)
    return out


def apply_kinds(outcomes: list, kinds: list, category: dict, exemplars=frozenset()) -> list:
    """The outcomes with every model withdrawn whose category is not the object's kind (``category``: model id ->
    its category) or which is one of the ``exemplars`` ``label`` stored (a kind's, never placed): a name is a
    claim, and a hedge of a car's size is no car however near a car model's sections come (reason code
    ``kind_not_model``; the model stays first among the candidates)."""
    out = []
    for res, kind in zip(outcomes, kinds):
        m = res.match
        mine = category.get(m.model_id) if m is not None else None
        if m is not None and (mine != kind.kind or m.model_id in exemplars):
            others = [c for c in res.candidates if c != m.model_id]
            what = "fits no catalogued kind" if kind.kind == UNKNOWN else f"is {kind.kind}"
            why = (f"the best model, {m.name}, is an exemplar of {mine} (label), never placed"
                   if m.model_id in exemplars else f"the best model, {m.name}, is a {mine}, but the object {what}")
            res = replace(res, match=None, candidates=[m.model_id, *others], reason=why,
                          reason_code="kind_not_model",
                          rejected={"name": m.name, "confidence": round(m.confidence or 0.0, 3)})
        out.append(res)
    return out
