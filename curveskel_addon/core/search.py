"""The search for J's minimum: continuous minimisation and topology moves, each kept only when
J falls.

    graph = first approximation, cut to the joint budget
    minimise J over joints and radii (the graph held)                -> "fit"
    merge chain joints while that lowers J (the other joints held)   -> "merge"
    repeat
        minimise J                                                  -> "fit"
        merge the chain joints whose removal lowers J                 -> "merge"
        prune the leaf branches whose removal lowers J                -> "prune"
        a joint into the bones that explain their share worst         -> "insert"
        split a junction in two, or join two into one, if J falls    -> "split" / "contract"
    until no move lowers J
    minimise J to convergence                                         -> "fit"

Candidate moves are ranked by estimates of their change of J (:mod:`.moves.gains`, computed
with the same term functions J uses, the other joints held); a batch of the best, touching no
common joint, is applied together and kept only if the exact J, after a few minimisation
steps, has fallen (else some of them alone). Every kept stage is logged with J and its terms:
J never rises from one logged stage to the next, and the graph returned is the lowest-J graph
seen. No move ever raises the joint count above the budget (*Max Joints*), and the budget is
met before the first stage is logged (:func:`budget`).
"""

from __future__ import annotations

import time

import numpy as np

from .config import CONFIG
from .moves.gains import merge_gains, prune_gains
from .moves.topology import (contract_bones, junction_splits, leaf_chains, merge_joints,
                             prune_chains, split_bones, split_joint)
from .objective.minimise import minimise

__all__ = ["search", "search_steps", "budget", "SearchLog"]


class SearchLog:
    """The stages the search kept: name, J, its terms (and the paper's E), joints, bones,
    seconds."""

    def __init__(self, objective=None):
        self.entries = []
        self.objective = objective
        self._t = time.perf_counter()

    def add(self, stage, graph, ev, **extra) -> dict:
        terms = {k: float(v) for k, v in ev.terms.items()}
        if self.objective is not None:
            terms["E"] = self.objective.paper_energy(graph)
        return self.add_value(stage, graph, ev.value, terms, **extra)

    def add_value(self, stage, graph, value, terms, **extra) -> dict:
        now = time.perf_counter()
        entry = {"stage": stage, "J": float(value), "terms": dict(terms),
                 "joints": int(graph.n_joints), "bones": int(len(graph.bones)),
                 "seconds": now - self._t, **extra}
        self.entries.append(entry)
        self._t = now
        return entry


def _levels(values, unit):
    """``values`` in whole ``unit``s (rounding of J: ``CONFIG.initial.tie`` of it), so that
    candidates whose estimates differ only in their last bits are equal, ranked by their
    number (the joints' order follows the shape: :mod:`.initialise.reeb`), and a gain is a
    gain only when it is more than rounding. A tie broken by the last bits would follow the
    input's (its numbering, a jitter of 1e-9, the order a sum is taken in), and one other
    choice early in the search leads to another skeleton."""
    return np.round(np.asarray(values, np.float64) / max(unit, 1e-300))


def _order(levels):
    """Best (lowest) first; equal levels in the candidates' own order."""
    return np.lexsort((np.arange(len(levels)), levels))


def _merge_batch(k, a, b, delta, bones, n_joints, *, gain=True, unit=0.0):
    """Candidates best first (with ``gain``: only those that lower J by more than rounding,
    ``unit``), no two touching the same joint, none whose two neighbours are already joined
    (the merge would fuse two bones)."""
    joined = {(int(x), int(y)) for x, y in np.sort(bones, axis=1)}
    used = np.zeros(n_joints, bool)
    out = []
    level = _levels(delta, unit) if unit > 0 else np.asarray(delta, np.float64)
    for c in _order(level):
        if gain and level[c] >= 0:
            break
        tri = [k[c], a[c], b[c]]
        if used[tri].any() or (min(a[c], b[c]), max(a[c], b[c])) in joined:
            continue
        used[tri] = True
        out.append(c)
    return np.asarray(out, np.int64)


def _lower(ev_new, ev_old):
    """Whether a move lowers J by more than rounding (``CONFIG.initial.tie`` of J): a decision
    on a difference in the last bits would follow the input's last bits (the summation order
    of a cross-section, a vertex jittered by 1e-9), not the shape."""
    return ev_new.value < ev_old.value - _unit(ev_old)


def _unit(ev):
    """J's rounding: the least change of J a decision may follow."""
    return CONFIG.initial.tie * abs(ev.value)


def _try(objective, graph, ev, make, batch, refit, singles=None):
    """Apply ``make(graph, batch)`` for the whole batch and keep it if the exact J falls (after
    ``refit`` minimisation steps; 0: the joints held). Otherwise the first few candidates are
    tried alone (an estimate holds sigma, which a move can shift): the batch without those that
    did not lower J is tried once more, else the best single kept. Returns (graph, ev, size) of
    the kept move, or None."""
    def attempt(bt):
        trial, _ = make(graph, bt)
        if refit:
            trial, ev_t, _ = minimise(objective, trial, max_iterations=refit,
                                      tolerance=CONFIG.search.round_tolerance)
        else:
            ev_t = objective.evaluate(trial)
        return trial, ev_t

    if not len(batch):
        return None
    trial, ev_t = attempt(batch)
    if _lower(ev_t, ev):
        return trial, ev_t, len(batch)
    if len(batch) == 1:
        return None
    n = min(CONFIG.search.singles if singles is None else singles, len(batch))
    good, best = [], None
    for i in range(n):
        tr, et = attempt(batch[i:i + 1])
        if _lower(et, ev):
            good.append(i)
            if best is None or et.value < best[1].value:
                best = (tr, et, 1)
    bad = [i for i in range(n) if i not in good]
    rest = np.delete(batch, bad)
    if len(rest) > 1 and bad:
        trial, ev_t = attempt(rest)
        if _lower(ev_t, ev) and (best is None or ev_t.value < best[1].value):
            return trial, ev_t, len(rest)
    return best


def _merges(objective, graph, ev, refit):
    """One round of merges: (graph, ev, count) or None."""
    k, a, b, delta = merge_gains(objective, graph, ev)
    batch = _merge_batch(k, a, b, delta, graph.bones, graph.n_joints, unit=_unit(ev))
    return _try(objective, graph, ev, lambda g, bt: merge_joints(g, k[bt]), batch, refit)


def _prunes(objective, graph, ev, refit):
    """One round of prunes (one chain per junction): (graph, ev, count) or None."""
    chains = [c for c in leaf_chains(graph) if c[2] >= 0]
    if not chains:
        return None
    delta = _levels(prune_gains(objective, graph, ev, chains), _unit(ev))
    seen, batch = set(), []
    for c in _order(delta):
        if delta[c] < 0 and chains[c][2] not in seen:
            seen.add(chains[c][2])
            batch.append(int(c))
    return _try(objective, graph, ev,
                lambda g, bt: prune_chains(g, [chains[c] for c in bt]),
                np.asarray(batch, np.int64), refit)


def _splits(objective, graph, ev, refit, max_joints):
    """One round of bone splits: a joint in the middle of each of the bones that explain
    their share of J worst (more than a joint's price), kept if J falls after ``refit``
    steps (the merges' counterpart: a chain merged too far, or a bone that must bend to stay
    inside, gets its joint back). (graph, ev, count) or None."""
    room = (max_joints - graph.n_joints) if max_joints else len(graph.bones)
    if room <= 0:
        return None
    share = _levels(objective.per_bone(graph, ev) - objective.weights.joint, _unit(ev))
    order = _order(-share)
    batch = order[share[order] > 0][:min(room, CONFIG.search.singles)]
    # no estimate ranks the bones better than their share: the batch, else the worst alone
    return _try(objective, graph, ev, lambda g, bt: split_bones(g, bt), batch, refit, singles=1)


def _junctions(objective, graph, ev, refit, max_joints):
    """The best of: a junction of four bones split in two (a crossing that is two
    junctions and a rung; not at the joint budget), or a bone between two junctions contracted
    (two junctions that are one), each evaluated with the joints held; kept if J falls after
    ``refit`` steps. Returns (graph, ev, kind) or None."""
    cands = []
    if not max_joints or graph.n_joints < max_joints:
        cands += [("split", c) for c in junction_splits(graph)]
    deg = graph.degree
    nbrs = [set() for _ in range(graph.n_joints)]
    for i, j in graph.bones.tolist():
        nbrs[i].add(j)
        nbrs[j].add(i)
    for b, (i, j) in enumerate(graph.bones.tolist()):
        if deg[i] >= 3 and deg[j] >= 3 and not (nbrs[i] & nbrs[j]):
            cands.append(("contract", b))
    best = None
    for kind, c in cands:
        trial = (split_joint(graph, *c, CONFIG.search.split_fraction) if kind == "split"
                 else contract_bones(graph, [c]))[0]
        ev_t = objective.evaluate(trial)
        if best is None or ev_t.value < best[1].value:
            best = (trial, ev_t, kind)
    if best is None:
        return None
    trial, ev_t, _ = minimise(objective, best[0], evaluation=best[1], max_iterations=refit,
                              tolerance=CONFIG.search.round_tolerance)
    if not _lower(ev_t, ev):
        return None
    return trial, ev_t, best[2]


def budget(objective, graph, max_joints):
    """``graph`` cut to at most ``max_joints`` joints (0: no limit), cheapest first: chain
    joints merged (by their estimated change of J), then, when only tips and junctions are
    left, the leaf chains pruned, then bones between junctions contracted. Not logged: the
    search starts from here."""
    if not max_joints:
        return graph
    while graph.n_joints > max_joints:
        ev = objective.evaluate(graph)
        excess = graph.n_joints - max_joints
        k, a, b, delta = merge_gains(objective, graph, ev)
        batch = _merge_batch(k, a, b, delta, graph.bones, graph.n_joints, gain=False,
                             unit=_unit(ev))[:excess]
        if len(batch):
            graph, _ = merge_joints(graph, k[batch])
            continue
        chains = [c for c in leaf_chains(graph) if c[2] >= 0]
        if chains:
            delta = prune_gains(objective, graph, ev, chains)
            graph, _ = prune_chains(graph, [chains[int(np.argmin(delta))]])
            continue
        deg = graph.degree
        inner = [b for b, (i, j) in enumerate(graph.bones.tolist()) if deg[i] >= 2 and deg[j] >= 2]
        contracted = False
        for b in inner:
            try:
                graph, _ = contract_bones(graph, [b])
                contracted = True
                break
            except ValueError:
                continue
        if not contracted:
            break                     # nothing left that keeps a graph: as small as it gets
    return graph


def search_steps(objective, graph, log: SearchLog, *, max_joints=0, max_iterations=None):
    """The search as a generator: yields ``(graph, log entry)`` after every kept stage; the
    last graph yielded is the one returned (the lowest J)."""
    cfg = CONFIG.search
    steps = cfg.rounds if max_iterations is None else max_iterations
    log.objective = objective
    ev = objective.evaluate(graph)
    yield graph, log.add("initialise", graph, ev)
    for _ in range(cfg.rounds):                      # merges with the joints held
        kept = _merges(objective, graph, ev, 0)
        if kept is None:
            break
        graph, ev, n = kept
        yield graph, log.add("merge", graph, ev, moved=int(n))
    for _ in range(cfg.rounds):
        changed = False
        g2, ev2, it = minimise(objective, graph, evaluation=ev, max_iterations=steps,
                               tolerance=cfg.round_tolerance)
        if ev2.value < ev.value:
            graph, ev = g2, ev2
            yield graph, log.add("fit", graph, ev, iterations=int(it))
        for name, move in (("merge", lambda: _merges(objective, graph, ev, 0)),
                           ("prune", lambda: _prunes(objective, graph, ev, cfg.refit_steps)),
                           ("insert", lambda: _splits(objective, graph, ev, cfg.refit_steps,
                                                      max_joints))):
            kept = move()
            if kept is not None:
                graph, ev, n = kept
                changed = True
                yield graph, log.add(name, graph, ev, moved=int(n))
        kept = _junctions(objective, graph, ev, cfg.refit_steps, max_joints)
        if kept is not None:
            graph, ev, kind = kept
            changed = True
            yield graph, log.add(kind, graph, ev)
        if not changed:
            break
    g2, ev2, it = minimise(objective, graph, evaluation=ev, max_iterations=steps,
                           tolerance=cfg.final_tolerance)
    if ev2.value < ev.value:
        graph, ev = g2, ev2
        yield graph, log.add("fit", graph, ev, iterations=int(it))


def search(objective, graph, *, max_joints=0, max_iterations=None):
    """Minimise J from ``graph``: (graph, log) of the lowest-J graph found."""
    log = SearchLog(objective)
    graph = budget(objective, graph, max_joints)
    for graph, _ in search_steps(objective, graph, log, max_joints=max_joints,
                                 max_iterations=max_iterations):
        pass
    return graph, log
