"""Numba kernels of the fleet search: inter- and intra-route local search and ruin-and-recreate for the
min-max objective (the makespan, then the total time).

The solution is planner.sortie_search's struct of arrays with one route slot per vehicle: ``routes[k]`` is
vehicle k's route depot_k, b1, ..., bj, depot_k (an idle vehicle keeps its slot as depot_k, depot_k), with
``route_of``, ``pos``, the prefix sums ``pref`` and the change memory ``stamp``/``tested`` maintained by the
same helpers (``refresh``, ``restore``, ``copy_solution``). The matrices given to them are D, the distances
(symmetric), as the arc "cost", and W, each buoy's dwell folded into the arcs that arrive at it
(planner.split.folded_matrices), as the arc "energy"; so pref[0] is a route's distance and pref[2] its dwell,
and vehicle k's route takes

    T_k = fixed_k + distance_k / speed_k + dwell_k   (0 for an idle vehicle).

``times[k]`` holds T_k and ``score`` = [makespan, total]. A move is improving when it lowers the makespan by
more than EPS, or keeps it (no route above it) and lowers the total by more than EPS: the lexicographic order,
so the search cannot cycle. Pricing a move touches one or two routes; the makespan after it is the max of their
new times and the longest other route, found in O(1) unless one of them is the longest (then O(K)).

Moves, for a buoy u and each v among its nearest buoys: relocate of 1-3 consecutive buoys starting at u next
to v, either way round (Or-opt within a route), and into an idle vehicle; swap of u and v between routes;
2-opt* (exchange of tails; each route keeps its own depot); 2-opt within a route. The granular memory skips a
pair whose routes did not change since u was last found without a move; a route that becomes the longest is
marked changed, since the moves that shorten the longest route are priced differently. When no such move is
left, every buoy of the longest route is tried at every place of every other route (the move that the
neighbour lists may miss: another route far away may have the slack).

Ruin-and-recreate: SISR's string removal (planner.sortie_search.ruin, idle vehicles kept), then each removed
buoy goes where it leaves the smallest makespan, the cheapest such place first (a 1 % blink as in SISR), then
the local search; simulated annealing on makespan + total_weight x total picks what is kept.
"""

from __future__ import annotations

import numpy as np

from planner.sortie_search import EPS, apply_relocate, copy_solution, join_routes, refresh, restore, ruin
from uavcore.kernel_cache import cached_kernel

# ----- times and the lexicographic score


@cached_kernel
def route_time(r, rlen, pref, inv_speed, fixed):
    """T_r from the prefix sums; 0 for an idle vehicle."""
    end = rlen[r] - 1
    if end <= 1:
        return 0.0
    return fixed[r] + pref[0, r, end] * inv_speed[r] + pref[2, r, end]


@cached_kernel
def _after_move(ra, ta, rb, tb, times, score):
    """(makespan, total) once route ra takes ta and rb takes tb (rb == ra for a change within one route)."""
    total = score[1] + ta - times[ra]
    if rb != ra:
        total += tb - times[rb]
    top = max(ta, tb)
    if times[ra] < score[0] and times[rb] < score[0]:
        return max(top, score[0]), total  # the longest route is among the others
    for r in range(len(times)):
        if r != ra and r != rb:
            top = max(top, times[r])
    return top, total


@cached_kernel
def _improves(makespan, total, score):
    return makespan < score[0] - EPS or (makespan <= score[0] and total < score[1] - EPS)


@cached_kernel
def _changed(r, sol, D, W):
    """Route r was rewritten: its prefix sums, positions and change stamp."""
    routes, rlen, info, route_of, pos, pref, stamp = sol[0], sol[1], sol[2], sol[3], sol[4], sol[5], sol[6]
    refresh(r, routes, rlen, route_of, pos, pref, D, W)
    info[1] += 1
    stamp[r] = info[1]


@cached_kernel
def update_score(sol, inv_speed, fixed):
    """Every route's time and the score, from the prefix sums; a route that became the longest is marked
    changed (the moves that shorten it were priced as if it were not the longest)."""
    rlen, info, pref, stamp, times, score = sol[1], sol[2], sol[5], sol[6], sol[8], sol[9]
    longest_before = np.argmax(times)
    for r in range(len(times)):
        times[r] = route_time(r, rlen, pref, inv_speed, fixed)
    longest = np.argmax(times)
    score[0] = times[longest]
    score[1] = times.sum()
    if longest != longest_before:
        info[1] += 1
        stamp[longest] = info[1]


# ----- local search moves (D symmetric: a stretch costs the same either way round)


@cached_kernel
def _try_relocate(u, rv, after, prob, sol, buf):
    """Relocate the stretch of 1..3 buoys starting at u to just after position ``after`` of route rv, either
    way round; the first improving one is applied."""
    D, W, inv_speed, fixed = prob[0], prob[1], prob[3], prob[4]
    routes, rlen, info, route_of, pos, pref, stamp, times, score = (
        sol[0], sol[1], sol[2], sol[3], sol[4], sol[5], sol[6], sol[8], sol[9])  # fmt: skip
    ru, iu = route_of[u], pos[u]
    end_u = rlen[ru] - 1
    a, b = routes[rv, after], routes[rv, after + 1]
    for length in range(1, 4):
        last = iu + length - 1
        if last > end_u - 1:
            break
        if ru == rv and iu - 1 <= after <= last:
            continue  # the place touches the stretch: no move
        p, q, x1, xl = routes[ru, iu - 1], routes[ru, last + 1], u, routes[ru, last]
        inner = pref[0, ru, last] - pref[0, ru, iu]
        dwell = pref[2, ru, last] - pref[2, ru, iu - 1]
        removal = D[p, q] - D[p, x1] - D[xl, q] - inner
        for rev in range(2 if length > 1 else 1):
            first, final = (x1, xl) if rev == 0 else (xl, x1)
            insertion = D[a, first] + inner + D[final, b] - D[a, b]
            if ru == rv:
                ta = times[ru] + (removal + insertion) * inv_speed[ru]
                tb = ta
            else:
                emptied = end_u - 1 == length
                ta = 0.0 if emptied else times[ru] + removal * inv_speed[ru] - dwell
                base = times[rv] if rlen[rv] > 2 else fixed[rv]
                tb = base + insertion * inv_speed[rv] + dwell
            makespan, total = _after_move(ru, ta, rv, tb, times, score)
            if _improves(makespan, total, score):
                apply_relocate(ru, iu, length, rv, after, rev == 1, routes, rlen, info, route_of, pos, pref, stamp,
                                buf, D, W)  # fmt: skip
                update_score(sol, inv_speed, fixed)
                return True
    return False


@cached_kernel
def _try_swap(u, v, prob, sol):
    """Exchange buoys u and v of two different routes."""
    D, dwell, inv_speed = prob[0], prob[2], prob[3]
    routes, route_of, pos, times, score = sol[0], sol[3], sol[4], sol[8], sol[9]
    ru, iu, rv, iv = route_of[u], pos[u], route_of[v], pos[v]
    if ru == rv:
        return False
    pu, qu, pv, qv = routes[ru, iu - 1], routes[ru, iu + 1], routes[rv, iv - 1], routes[rv, iv + 1]
    ta = times[ru] + (D[pu, v] + D[v, qu] - D[pu, u] - D[u, qu]) * inv_speed[ru] + dwell[v] - dwell[u]
    tb = times[rv] + (D[pv, u] + D[u, qv] - D[pv, v] - D[v, qv]) * inv_speed[rv] + dwell[u] - dwell[v]
    makespan, total = _after_move(ru, ta, rv, tb, times, score)
    if not _improves(makespan, total, score):
        return False
    routes[ru, iu], routes[rv, iv] = v, u
    _changed(ru, sol, D, prob[1])
    _changed(rv, sol, D, prob[1])
    update_score(sol, inv_speed, prob[4])
    return True


@cached_kernel
def _joined_time(ra, i, rb, j, prob, sol):
    """Time of route ra's head (positions 0..i) followed by route rb's tail (its buoys after position j),
    flown back to ra's depot; 0 when that holds no buoy."""
    D, inv_speed, fixed = prob[0], prob[3], prob[4]
    routes, rlen, pref = sol[0], sol[1], sol[5]
    end_b = rlen[rb] - 1
    a, home = routes[ra, i], routes[ra, 0]
    length, dwell = pref[0, ra, i], pref[2, ra, i]
    if j + 1 <= end_b - 1:
        first, last = routes[rb, j + 1], routes[rb, end_b - 1]
        length += D[a, first] + pref[0, rb, end_b - 1] - pref[0, rb, j + 1] + D[last, home]
        dwell += pref[2, rb, end_b - 1] - pref[2, rb, j]
    elif i == 0:
        return 0.0
    else:
        length += D[a, home]
    return fixed[ra] + length * inv_speed[ra] + dwell


@cached_kernel
def _try_two_opt_star(ru, i, rv, j, prob, sol, buf):
    """2-opt*: route ru keeps its positions 0..i and takes rv's buoys after position j, rv keeps 0..j and takes
    ru's buoys after i; each flies home to its own depot."""
    routes, rlen, times, score = sol[0], sol[1], sol[8], sol[9]
    end_r, end_s = rlen[ru] - 1, rlen[rv] - 1
    if i < 0 or j < 0 or (i + 1 == end_r and j + 1 == end_s):
        return False  # no tail to exchange
    ta = _joined_time(ru, i, rv, j, prob, sol)
    tb = _joined_time(rv, j, ru, i, prob, sol)
    makespan, total = _after_move(ru, ta, rv, tb, times, score)
    if not _improves(makespan, total, score):
        return False
    k1 = join_routes(buf[0], routes, ru, i, rv, j + 1, end_s - 1)
    k2 = join_routes(buf[1], routes, rv, j, ru, i + 1, end_r - 1)
    buf[0, k1], buf[1, k2] = routes[ru, 0], routes[rv, 0]
    routes[ru, : k1 + 1] = buf[0, : k1 + 1]
    routes[rv, : k2 + 1] = buf[1, : k2 + 1]
    rlen[ru], rlen[rv] = k1 + 1, k2 + 1
    _changed(ru, sol, prob[0], prob[1])
    _changed(rv, sol, prob[0], prob[1])
    update_score(sol, prob[3], prob[4])
    return True


@cached_kernel
def _try_reverse(r, s, t, prob, sol):
    """2-opt within route r: reverse positions s..t (1 <= s < t <= rlen - 2)."""
    D, inv_speed = prob[0], prob[3]
    routes, rlen, times, score = sol[0], sol[1], sol[8], sol[9]
    if s < 1 or t <= s or t > rlen[r] - 2:
        return False
    a, b, c, d = routes[r, s - 1], routes[r, s], routes[r, t], routes[r, t + 1]
    ta = times[r] + (D[a, c] + D[b, d] - D[a, b] - D[c, d]) * inv_speed[r]
    makespan, total = _after_move(r, ta, r, ta, times, score)
    if not _improves(makespan, total, score):
        return False
    while s < t:
        routes[r, s], routes[r, t] = routes[r, t], routes[r, s]
        s += 1
        t -= 1
    _changed(r, sol, D, prob[1])
    update_score(sol, inv_speed, prob[4])
    return True


@cached_kernel
def _try_pair(u, v, prob, sol, buf):
    """The first improving move around the pair of buoys (u, v), applied; whether there was one."""
    route_of, pos = sol[3], sol[4]
    for x, y in ((u, v), (v, u)):
        ry, iy = route_of[y], pos[y]
        if _try_relocate(x, ry, iy, prob, sol, buf) or _try_relocate(x, ry, iy - 1, prob, sol, buf):
            return True
    ru, iu, rv, iv = route_of[u], pos[u], route_of[v], pos[v]
    if ru != rv:
        if _try_swap(u, v, prob, sol):
            return True
        return _try_two_opt_star(ru, iu, rv, iv - 1, prob, sol, buf) or _try_two_opt_star(
            ru, iu - 1, rv, iv, prob, sol, buf
        )
    lo, hi = min(iu, iv), max(iu, iv)
    return _try_reverse(ru, lo + 1, hi, prob, sol) or _try_reverse(ru, lo, hi - 1, prob, sol)


@cached_kernel
def _unload_longest(prob, sol, buf):
    """The best relocation of one buoy of the longest route to any place of any other route, applied when it
    improves; whether it did."""
    D, dwell, inv_speed, fixed = prob[0], prob[2], prob[3], prob[4]
    routes, rlen, times, score = sol[0], sol[1], sol[8], sol[9]
    ru = np.argmax(times)
    best_makespan, best_total = score[0], score[1]
    best_u, best_rv, best_after = -1, -1, -1
    for iu in range(1, rlen[ru] - 1):
        p, u, q = routes[ru, iu - 1], routes[ru, iu], routes[ru, iu + 1]
        ta = 0.0 if rlen[ru] == 3 else times[ru] + (D[p, q] - D[p, u] - D[u, q]) * inv_speed[ru] - dwell[u]
        for rv in range(len(times)):
            if rv == ru:
                continue
            base = (times[rv] if rlen[rv] > 2 else fixed[rv]) + dwell[u]
            for after in range(rlen[rv] - 1):
                a, b = routes[rv, after], routes[rv, after + 1]
                tb = base + (D[a, u] + D[u, b] - D[a, b]) * inv_speed[rv]
                makespan, total = _after_move(ru, ta, rv, tb, times, score)
                if makespan < best_makespan - EPS or (makespan <= best_makespan and total < best_total - EPS):
                    best_makespan, best_total, best_u, best_rv, best_after = makespan, total, iu, rv, after
    if best_u < 0:
        return False
    apply_relocate(ru, best_u, 1, best_rv, best_after, False, routes, rlen, sol[2], sol[3], sol[4], sol[5], sol[6],
                    buf, D, prob[1])  # fmt: skip
    update_score(sol, inv_speed, fixed)
    return True


@cached_kernel
def local_search(prob, buoys, neigh, sol, buf):
    """First-improvement local search to a local optimum of every move, visiting buoys in random order."""
    rlen, info, route_of, stamp, tested = sol[1], sol[2], sol[3], sol[6], sol[7]
    order = buoys.copy()
    K = len(rlen)
    while True:
        improved = False
        np.random.shuffle(order)
        for u in order:
            while True:
                moved = False
                seen = tested[u]
                for t in range(neigh.shape[1]):
                    v = neigh[u, t]
                    if stamp[route_of[u]] <= seen and stamp[route_of[v]] <= seen:
                        continue  # neither route changed since u was last found without a move
                    if _try_pair(u, v, prob, sol, buf):
                        moved = True
                        break
                rv = 0
                while not moved and rv < K:  # into an idle vehicle
                    if rlen[rv] == 2 and (stamp[rv] > seen or stamp[route_of[u]] > seen):
                        moved = _try_relocate(u, rv, 0, prob, sol, buf)
                    rv += 1
                if not moved:
                    tested[u] = info[1]
                    break
                improved = True
        if not improved and not _unload_longest(prob, sol, buf):
            return


# ----- ruin and recreate


@cached_kernel
def _recreate(count, removed, is_removed, blink, prob, sol):
    """Greedy insertion with blinks (SISR Section 4.2, min-max form): buoys in random order, or farthest /
    closest to their nearest depot first; each where it leaves the least makespan, then the least added time."""
    D, dwell, inv_speed, fixed = prob[0], prob[2], prob[3], prob[4]
    routes, rlen, times, score = sol[0], sol[1], sol[8], sol[9]
    K = len(times)
    chosen = removed[:count]
    draw = np.random.randint(7)  # SISR's weights: random 4, (demand 4: no loads here), far 2, close 1
    if draw < 4:
        np.random.shuffle(chosen)
    else:
        key = np.empty(count)
        for k in range(count):
            key[k] = np.inf
            for r in range(K):
                key[k] = min(key[k], D[routes[r, 0], chosen[k]])
        order = np.argsort(key)
        if draw < 6:
            order = order[::-1]
        chosen[:] = chosen[order]
    for k in range(count):
        c = chosen[k]
        best_makespan, best_added, best_r, best_after = np.inf, np.inf, -1, -1
        for r in range(K):
            base = (times[r] if rlen[r] > 2 else fixed[r]) + dwell[c]
            for p in range(rlen[r] - 1):
                if np.random.random() < blink:
                    continue
                a, b = routes[r, p], routes[r, p + 1]
                t = base + (D[a, c] + D[c, b] - D[a, b]) * inv_speed[r]
                makespan, added = max(t, score[0]), t - times[r]
                if makespan < best_makespan or (makespan == best_makespan and added < best_added):
                    best_makespan, best_added, best_r, best_after = makespan, added, r, p
        if best_r < 0:  # every place blinked: the first one
            best_r, best_after = 0, 0
        for t in range(rlen[best_r] - 1, best_after, -1):
            routes[best_r, t + 1] = routes[best_r, t]
        routes[best_r, best_after + 1] = c
        rlen[best_r] += 1
        _changed(best_r, sol, D, prob[1])
        times[best_r] = route_time(best_r, rlen, sol[5], inv_speed, fixed)
        score[0] = max(score[0], times[best_r])
        is_removed[c] = False
    update_score(sol, inv_speed, fixed)


@cached_kernel
def search(prob, buoys, neigh, adj, sol, buf, cur, best, costs, iterations, temp_start, temp_end, search_params):
    """``iterations`` rounds of ruin, recreate, local search and simulated-annealing acceptance on
    makespan + total_weight x total (accept when below the current value - T ln U; T falls geometrically from
    temp_start to temp_end over the rounds). ``cur`` and ``best`` are (routes, rlen, info) copies;
    costs = [current value, best makespan, best total]: the best is kept in the lexicographic order.
    search_params = (mean_removed, max_string, blink, total_weight, with_local_search)."""
    mean_removed, max_string, blink, total_weight, with_local_search = search_params
    routes, rlen, info, route_of, pos, pref, stamp = sol[0], sol[1], sol[2], sol[3], sol[4], sol[5], sol[6]
    score = sol[9]
    D, W = prob[0], prob[1]
    n = D.shape[0]
    removed = np.empty(n, dtype=np.int64)
    is_removed = np.zeros(n, dtype=np.bool_)
    for it in range(iterations):
        temperature = temp_start * (temp_end / temp_start) ** (it / max(1, iterations))
        count = ruin(buoys, adj, mean_removed, max_string, False, routes, rlen, info, route_of, pos, pref, stamp,
                     removed, is_removed, D, W)  # fmt: skip
        update_score(sol, prob[3], prob[4])
        _recreate(count, removed, is_removed, blink, prob, sol)
        if with_local_search:
            local_search(prob, buoys, neigh, sol, buf)
        value = score[0] + total_weight * score[1]
        if value < costs[0] - temperature * np.log(np.random.random()):
            copy_solution(routes, rlen, info, cur[0], cur[1], cur[2])
            costs[0] = value
            if score[0] < costs[1] - EPS or (score[0] <= costs[1] and score[1] < costs[2] - EPS):
                copy_solution(routes, rlen, info, best[0], best[1], best[2])
                costs[1], costs[2] = score[0], score[1]
        else:
            restore(cur[0], cur[1], cur[2], routes, rlen, info, route_of, pos, pref, stamp, D, W)
            update_score(sol, prob[3], prob[4])
