"""The search for J's minimum: continuous minimisation and topology moves, each kept only when
J falls.

    graph = first approximation
    repeat
        minimise J over joints and radii (the graph held)             -> "fit"
        merge the chain joints whose removal lowers J                   -> "merge"
        prune the leaf branches whose removal lowers J                  -> "prune"
    until no move lowers J

A batch of merges is chosen from estimates of each one's change of J (:mod:`.moves.gains`),
applied together, the joints fitted again, and kept only if the exact J has fallen; else the
better half of the batch is tried, down to one. Every kept stage is logged with J and its
terms, so J never rises from one logged stage to the next, and the graph returned is the
lowest-J graph seen.
"""

from __future__ import annotations

import time

import numpy as np

from .moves.gains import merge_gains
from .moves.topology import leaf_chains, merge_joints, prune_chains
from .objective.minimise import minimise

__all__ = ["search", "SearchLog"]


class SearchLog:
    """The stages the search kept: name, J, its terms, joints, bones, seconds."""

    def __init__(self):
        self.entries = []
        self._t = time.perf_counter()

    def add(self, stage, graph, ev, **extra):
        now = time.perf_counter()
        self.entries.append({"stage": stage, "J": float(ev.value),
                             "terms": {k: float(v) for k, v in ev.terms.items()},
                             "joints": int(graph.n_joints), "bones": int(len(graph.bones)),
                             "seconds": now - self._t, **extra})
        self._t = now


def _batch(k, a, b, delta, bones, n_joints):
    """Candidates with delta < 0, best first, no two touching the same joint, none whose two
    neighbours are already joined (the merge would fuse two bones)."""
    joined = {(int(x), int(y)) for x, y in np.sort(bones, axis=1)}
    used = np.zeros(n_joints, bool)
    out = []
    for c in np.argsort(delta, kind="stable"):
        if delta[c] >= 0:
            break
        tri = (k[c], a[c], b[c])
        if used[list(tri)].any() or (min(a[c], b[c]), max(a[c], b[c])) in joined:
            continue
        used[list(tri)] = True
        out.append(c)
    return np.asarray(out, np.int64)


def search(objective, graph, log: SearchLog, *, max_rounds=50, refit_iterations=8,
           max_iterations=100, tolerance=1e-7):
    """Minimise J from ``graph``; returns (graph, evaluation)."""
    ev = objective.evaluate(graph)
    log.add("initialise", graph, ev)
    graph, ev, it = minimise(objective, graph, evaluation=ev, max_iterations=max_iterations,
                             tolerance=tolerance)
    log.add("fit", graph, ev, iterations=int(it))
    for _ in range(max_rounds):
        changed = False
        k, a, b, delta = merge_gains(objective, graph, ev)
        batch = _batch(k, a, b, delta, graph.bones, graph.n_joints)
        while len(batch):
            trial, _ = merge_joints(graph, k[batch])
            trial, ev_t, _ = minimise(objective, trial, max_iterations=refit_iterations,
                                      tolerance=tolerance)
            if ev_t.value < ev.value:
                graph, ev, changed = trial, ev_t, True
                log.add("merge", graph, ev, merged=int(len(batch)))
                break
            batch = batch[:len(batch) // 2]
        best = None
        for chain in leaf_chains(graph):
            if chain[2] < 0:
                continue
            trial, _ = prune_chains(graph, [chain])
            ev_t = objective.evaluate(trial)
            if best is None or ev_t.value < best[1].value:
                best = (trial, ev_t)
        if best is not None:
            trial, ev_t, _ = minimise(objective, best[0], evaluation=best[1],
                                      max_iterations=refit_iterations, tolerance=tolerance)
            if ev_t.value < ev.value:
                graph, ev, changed = trial, ev_t, True
                log.add("prune", graph, ev)
        if not changed:
            break
    graph2, ev2, it = minimise(objective, graph, evaluation=ev, max_iterations=max_iterations,
                               tolerance=tolerance)
    if ev2.value < ev.value:
        graph, ev = graph2, ev2
        log.add("fit", graph, ev, iterations=int(it))
    return graph, ev
