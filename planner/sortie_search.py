"""Numba kernels of the multi-sortie search: a solution as a set of routes, the inter- and intra-route local
search, and ruin-and-recreate, all with the energy check and asymmetric arc costs.

A solution is a small struct of arrays (``Routes`` in planner.sorties builds it):
- ``routes[r, :rlen[r]]`` is route r as 0, b1, ..., bk, 0 (slots 0..info[0]-1 are in use, none empty);
- ``route_of[b]``, ``pos[b]``: where buoy b is;
- ``pref[0, r, k]`` = cost of route r's first k arcs flown forward, ``pref[1, r, k]`` the same arcs flown
  backward (what reversing a stretch costs), ``pref[2]``, ``pref[3]`` likewise for energy: with them a 2-opt or
  2-opt* move is priced in O(1) although A->B and B->A differ;
- ``stamp[r]``: the move counter when route r last changed; ``tested[u]``: the counter when buoy u last had no
  improving move. A pair (u, v) is skipped when neither route changed since (Vidal et al. 2012's granular
  search memory), so a local search after a small change costs little.
C and E are the arc matrices with the node services folded in (planner.split.folded_matrices); a route is
feasible when its arc energy <= capacity (the budget less the fixed per-sortie energy); each used route costs
``fixed`` on top of its arcs.

Moves of the local search, for a buoy u and each v among its nearest: relocate of the stretch of 1-3 buoys
starting at u next to v (before or after it, either way round; within a route this is Or-opt), swap of u and
v between routes, 2-opt* (exchange of the routes' tails so that u->v or v->u becomes an arc) and, within a
route, 2-opt (reversal of the stretch between them). First improvement, to a local optimum.

Ruin and recreate is SISR (Christiaens & Vanden Berghe 2020, "Slack induction by string removals for vehicle
routing problems", Transportation Science 54(2)): remove a few strings of consecutive buoys from routes near a
random buoy, reinsert each removed buoy at its cheapest feasible place (skipping each place with a small
"blink" probability), opening a new sortie when none fits or that is cheaper.
"""

from __future__ import annotations

import numpy as np

from uavcore.kernel_cache import cached_kernel

EPS = 1e-7  # improvements smaller than this (s or m) are rounding noise of the prefix sums: no move cycles


# ----- the solution's bookkeeping


@cached_kernel
def refresh(r, routes, rlen, route_of, pos, pref, C, E):
    """Recompute route r's prefix sums and where its buoys are (after any change to it)."""
    L = rlen[r]
    for q in range(4):
        pref[q, r, 0] = 0.0
    for k in range(L):
        node = routes[r, k]
        if 0 < k < L - 1:
            route_of[node] = r
            pos[node] = k
        if k + 1 < L:
            nxt = routes[r, k + 1]
            pref[0, r, k + 1] = pref[0, r, k] + C[node, nxt]
            pref[1, r, k + 1] = pref[1, r, k] + C[nxt, node]
            pref[2, r, k + 1] = pref[2, r, k] + E[node, nxt]
            pref[3, r, k + 1] = pref[3, r, k] + E[nxt, node]


@cached_kernel
def _touch(r, stamp, info):
    info[1] += 1
    stamp[r] = info[1]


@cached_kernel
def _drop_route(r, routes, rlen, info, route_of, pos, pref, stamp, C, E):
    """Remove the (empty) route in slot r: the last used slot moves into it."""
    last = info[0] - 1
    if r != last:
        for k in range(rlen[last]):
            routes[r, k] = routes[last, k]
        rlen[r] = rlen[last]
        refresh(r, routes, rlen, route_of, pos, pref, C, E)
        _touch(r, stamp, info)
    info[0] = last


@cached_kernel
def _drop_empty_routes(routes, rlen, info, route_of, pos, pref, stamp, C, E):
    for r in range(info[0] - 1, -1, -1):
        if rlen[r] == 2:
            _drop_route(r, routes, rlen, info, route_of, pos, pref, stamp, C, E)


@cached_kernel
def total_cost(pref, rlen, info, fixed):
    """Objective of the solution: every route's arcs plus the fixed part per route."""
    total = 0.0
    for r in range(info[0]):
        total += pref[0, r, rlen[r] - 1] + fixed
    return total


@cached_kernel
def copy_solution(src_routes, src_rlen, src_info, dst_routes, dst_rlen, dst_info):
    """Copy the routes in use (O(n)), e.g. the working solution into the current or the best one."""
    for r in range(src_info[0]):
        L = src_rlen[r]
        dst_rlen[r] = L
        for k in range(L):
            dst_routes[r, k] = src_routes[r, k]
    dst_info[0] = src_info[0]


@cached_kernel
def restore(src_routes, src_rlen, src_info, routes, rlen, info, route_of, pos, pref, stamp, C, E):
    """Make the working solution equal to src again; only the routes that differ are rewritten (and marked
    changed for the local search's memory)."""
    for r in range(src_info[0]):
        L = src_rlen[r]
        same = r < info[0] and rlen[r] == L
        if same:
            for k in range(L):
                if routes[r, k] != src_routes[r, k]:
                    same = False
                    break
        if not same:
            for k in range(L):
                routes[r, k] = src_routes[r, k]
            rlen[r] = L
            refresh(r, routes, rlen, route_of, pos, pref, C, E)
            _touch(r, stamp, info)
    info[0] = src_info[0]


# ----- local search moves


@cached_kernel
def apply_relocate(ru, start, length, rv, after, rev, routes, rlen, info, route_of, pos, pref, stamp, buf, C, E):
    """Move the stretch routes[ru, start:start+length] to just after position ``after`` of route rv (a route
    left empty stays in its slot: the caller drops it, or keeps it as an idle vehicle of planner.fleet)."""
    last = start + length - 1
    seg = buf[1]
    for s in range(length):
        seg[s] = routes[ru, last - s] if rev else routes[ru, start + s]
    out = buf[0]
    k = 0
    for t in range(rlen[rv]):
        if rv == ru and start <= t <= last:
            continue
        out[k] = routes[rv, t]
        k += 1
        if t == after:
            for s in range(length):
                out[k] = seg[s]
                k += 1
    for t in range(k):
        routes[rv, t] = out[t]
    rlen[rv] = k
    refresh(rv, routes, rlen, route_of, pos, pref, C, E)
    _touch(rv, stamp, info)
    if ru != rv:
        for t in range(last + 1, rlen[ru]):
            routes[ru, t - length] = routes[ru, t]
        rlen[ru] -= length
        refresh(ru, routes, rlen, route_of, pos, pref, C, E)
        _touch(ru, stamp, info)


@cached_kernel
def _try_relocate(u, v, C, E, fixed, cap, routes, rlen, info, route_of, pos, pref, stamp, buf):
    """Relocate the stretch of 1..3 buoys starting at u to just before or after v, either way round."""
    ru, iu, rv, iv = route_of[u], pos[u], route_of[v], pos[v]
    end_u = rlen[ru] - 1
    energy_u = pref[2, ru, end_u]
    energy_v = pref[2, rv, rlen[rv] - 1]
    for length in range(1, 4):
        last = iu + length - 1
        if last > end_u - 1 or (ru == rv and iu <= iv <= last):
            break
        p, q, x1, xl = routes[ru, iu - 1], routes[ru, last + 1], u, routes[ru, last]
        inner_fc = pref[0, ru, last] - pref[0, ru, iu]
        inner_rc = pref[1, ru, last] - pref[1, ru, iu]
        inner_fe = pref[2, ru, last] - pref[2, ru, iu]
        inner_re = pref[3, ru, last] - pref[3, ru, iu]
        removal_c = C[p, q] - C[p, x1] - C[xl, q] - inner_fc
        removal_e = E[p, q] - E[p, x1] - E[xl, q] - inner_fe
        emptied = ru != rv and end_u - 1 == length
        for side in range(2):
            after = iv if side == 0 else iv - 1
            if ru == rv and iu - 1 <= after <= last:
                continue  # the place touches the stretch: no move
            a, b = routes[rv, after], routes[rv, after + 1]
            for rev in range(2 if length > 1 else 1):
                if rev == 0:
                    insert_c = C[a, x1] + inner_fc + C[xl, b] - C[a, b]
                    insert_e = E[a, x1] + inner_fe + E[xl, b] - E[a, b]
                else:
                    insert_c = C[a, xl] + inner_rc + C[x1, b] - C[a, b]
                    insert_e = E[a, xl] + inner_re + E[x1, b] - E[a, b]
                delta = removal_c + insert_c - (fixed if emptied else 0.0)
                if delta >= -EPS:
                    continue
                if ru == rv:
                    feasible = energy_u + removal_e + insert_e <= cap
                else:
                    feasible = energy_u + removal_e <= cap and energy_v + insert_e <= cap
                if feasible:
                    apply_relocate(
                        ru, iu, length, rv, after, rev == 1, routes, rlen, info, route_of, pos, pref, stamp, buf, C, E
                    )
                    if emptied:
                        _drop_route(ru, routes, rlen, info, route_of, pos, pref, stamp, C, E)
                    return True
    return False


@cached_kernel
def _try_swap(u, v, C, E, cap, routes, rlen, info, route_of, pos, pref, stamp):
    """Exchange buoys u and v of two different routes."""
    ru, iu, rv, iv = route_of[u], pos[u], route_of[v], pos[v]
    if ru == rv:
        return False
    pu, qu, pv, qv = routes[ru, iu - 1], routes[ru, iu + 1], routes[rv, iv - 1], routes[rv, iv + 1]
    dcu = C[pu, v] + C[v, qu] - C[pu, u] - C[u, qu]
    dcv = C[pv, u] + C[u, qv] - C[pv, v] - C[v, qv]
    if dcu + dcv >= -EPS:
        return False
    deu = E[pu, v] + E[v, qu] - E[pu, u] - E[u, qu]
    dev = E[pv, u] + E[u, qv] - E[pv, v] - E[v, qv]
    if pref[2, ru, rlen[ru] - 1] + deu > cap or pref[2, rv, rlen[rv] - 1] + dev > cap:
        return False
    routes[ru, iu], routes[rv, iv] = v, u
    refresh(ru, routes, rlen, route_of, pos, pref, C, E)
    refresh(rv, routes, rlen, route_of, pos, pref, C, E)
    _touch(ru, stamp, info)
    _touch(rv, stamp, info)
    return True


@cached_kernel
def join_routes(out, routes, head_route, head_end, tail_route, tail_start, tail_end):
    """out = routes[head_route, 0..head_end] followed by routes[tail_route, tail_start..tail_end]; its length."""
    k = 0
    for t in range(head_end + 1):
        out[k] = routes[head_route, t]
        k += 1
    for t in range(tail_start, tail_end + 1):
        out[k] = routes[tail_route, t]
        k += 1
    return k


@cached_kernel
def _try_two_opt_star(ru, i, rv, j, C, E, fixed, cap, routes, rlen, info, route_of, pos, pref, stamp, buf):
    """2-opt*: route ru keeps its positions 0..i and takes rv's tail after j; rv keeps 0..j and takes ru's
    tail after i (no stretch is reversed, so the asymmetric costs need only the forward prefix sums)."""
    end_r, end_s = rlen[ru] - 1, rlen[rv] - 1
    if i < 0 or j < 0 or (i == 0 and j == 0) or (i + 1 == end_r and j + 1 == end_s):
        return False  # swapping whole routes or empty tails changes nothing
    a, b, c, d = routes[ru, i], routes[ru, i + 1], routes[rv, j], routes[rv, j + 1]
    new_r = pref[0, ru, i] + C[a, d] + pref[0, rv, end_s] - pref[0, rv, j + 1]
    new_s = pref[0, rv, j] + C[c, b] + pref[0, ru, end_r] - pref[0, ru, i + 1]
    emptied = (1 if (i == 0 and j + 1 == end_s) else 0) + (1 if (j == 0 and i + 1 == end_r) else 0)
    delta = new_r + new_s - pref[0, ru, end_r] - pref[0, rv, end_s] - emptied * fixed
    if delta >= -EPS:
        return False
    if pref[2, ru, i] + E[a, d] + pref[2, rv, end_s] - pref[2, rv, j + 1] > cap:
        return False
    if pref[2, rv, j] + E[c, b] + pref[2, ru, end_r] - pref[2, ru, i + 1] > cap:
        return False
    k1 = join_routes(buf[0], routes, ru, i, rv, j + 1, end_s)
    k2 = join_routes(buf[1], routes, rv, j, ru, i + 1, end_r)
    routes[ru, :k1] = buf[0, :k1]
    routes[rv, :k2] = buf[1, :k2]
    rlen[ru], rlen[rv] = k1, k2
    for r in (ru, rv):
        refresh(r, routes, rlen, route_of, pos, pref, C, E)
        _touch(r, stamp, info)
    for r in (max(ru, rv), min(ru, rv)):  # drop the higher slot first: dropping moves the last slot
        if rlen[r] == 2:
            _drop_route(r, routes, rlen, info, route_of, pos, pref, stamp, C, E)
    return True


@cached_kernel
def _try_reverse(r, s, t, C, E, cap, routes, rlen, info, route_of, pos, pref, stamp):
    """2-opt within route r: reverse positions s..t (1 <= s < t <= rlen - 2), priced with the backward sums."""
    if s < 1 or t <= s or t > rlen[r] - 2:
        return False
    a, b, c, d = routes[r, s - 1], routes[r, s], routes[r, t], routes[r, t + 1]
    dc = C[a, c] + C[b, d] - C[a, b] - C[c, d] + (pref[1, r, t] - pref[1, r, s]) - (pref[0, r, t] - pref[0, r, s])
    if dc >= -EPS:
        return False
    de = E[a, c] + E[b, d] - E[a, b] - E[c, d] + (pref[3, r, t] - pref[3, r, s]) - (pref[2, r, t] - pref[2, r, s])
    if pref[2, r, rlen[r] - 1] + de > cap:
        return False
    while s < t:
        routes[r, s], routes[r, t] = routes[r, t], routes[r, s]
        s += 1
        t -= 1
    refresh(r, routes, rlen, route_of, pos, pref, C, E)
    _touch(r, stamp, info)
    return True


@cached_kernel
def _try_pair(u, v, C, E, fixed, cap, routes, rlen, info, route_of, pos, pref, stamp, buf):
    """The first improving feasible move around the pair (u, v), applied; whether there was one."""
    if _try_relocate(u, v, C, E, fixed, cap, routes, rlen, info, route_of, pos, pref, stamp, buf):
        return True
    if _try_relocate(v, u, C, E, fixed, cap, routes, rlen, info, route_of, pos, pref, stamp, buf):
        return True
    ru, iu, rv, iv = route_of[u], pos[u], route_of[v], pos[v]
    if ru != rv:
        if _try_swap(u, v, C, E, cap, routes, rlen, info, route_of, pos, pref, stamp):
            return True
        if _try_two_opt_star(ru, iu, rv, iv - 1, C, E, fixed, cap, routes, rlen, info, route_of, pos, pref, stamp, buf):
            return True
        return _try_two_opt_star(
            ru, iu - 1, rv, iv, C, E, fixed, cap, routes, rlen, info, route_of, pos, pref, stamp, buf
        )
    lo, hi = min(iu, iv), max(iu, iv)
    if _try_reverse(ru, lo + 1, hi, C, E, cap, routes, rlen, info, route_of, pos, pref, stamp):
        return True
    return _try_reverse(ru, lo, hi - 1, C, E, cap, routes, rlen, info, route_of, pos, pref, stamp)


@cached_kernel
def local_search(C, E, fixed, cap, neigh, routes, rlen, info, route_of, pos, pref, stamp, tested, buf):
    """First-improvement local search to a local optimum of every move, visiting buoys in random order."""
    n = C.shape[0]
    order = np.arange(1, n)
    improved = True
    while improved:
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
                    if _try_pair(u, v, C, E, fixed, cap, routes, rlen, info, route_of, pos, pref, stamp, buf):
                        moved = True
                        break
                if not moved:
                    tested[u] = info[1]
                    break
                improved = True


# ----- ruin and recreate (SISR)


@cached_kernel
def ruin(buoys, adj, mean_removed, max_string, drop_empty, routes, rlen, info, route_of, pos, pref, stamp, removed,
         is_removed, C, E):  # fmt: skip
    """SISR's string removal around a random seed buoy (Christiaens & Vanden Berghe 2020, Section 4.1): at most
    one string per route, k_s routes, each string of length <= l_s_max. ``buoys`` lists the buoy nodes, ``adj``
    each buoy's nearest buoys; routes left empty are dropped when drop_empty (sorties) or kept (a fleet's idle
    vehicles). Returns how many buoys were removed."""
    nr = info[0]
    l_s_max = min(float(max_string), len(buoys) / nr)
    k_s_max = 4.0 * mean_removed / (1.0 + l_s_max) - 1.0
    k_s = int(np.random.random() * k_s_max) + 1
    ruined = np.zeros(nr, dtype=np.bool_)
    seed = buoys[np.random.randint(len(buoys))]
    count = 0
    strings = 0
    for t in range(-1, adj.shape[1]):
        if strings >= k_s:
            break
        c = seed if t < 0 else adj[seed, t]
        if is_removed[c] or ruined[route_of[c]]:
            continue
        r = route_of[c]
        size = rlen[r] - 2
        l_max = min(float(size), l_s_max)
        length = min(size, int(np.random.random() * l_max) + 1)
        lo = max(1, pos[c] - length + 1)
        hi = min(pos[c], size - length + 1)
        start = lo + np.random.randint(hi - lo + 1)
        for k in range(start, start + length):
            removed[count] = routes[r, k]
            is_removed[routes[r, k]] = True
            count += 1
        for k in range(start + length, rlen[r]):
            routes[r, k - length] = routes[r, k]
        rlen[r] -= length
        refresh(r, routes, rlen, route_of, pos, pref, C, E)
        _touch(r, stamp, info)
        ruined[r] = True
        strings += 1
    if drop_empty:
        _drop_empty_routes(routes, rlen, info, route_of, pos, pref, stamp, C, E)
    return count


@cached_kernel
def _recreate(count, blink, fixed, cap, routes, rlen, info, route_of, pos, pref, stamp, removed, is_removed, C, E):
    """Greedy insertion with blinks (SISR Section 4.2): buoys in random order, or farthest / closest first."""
    draw = np.random.randint(7)  # SISR's weights: random 4, (demand 4: no loads here), far 2, close 1
    chosen = removed[:count]
    if draw < 4:
        np.random.shuffle(chosen)
    else:
        key = np.empty(count)
        for k in range(count):
            key[k] = C[0, chosen[k]] + C[chosen[k], 0]
        order = np.argsort(key)
        if draw < 6:
            order = order[::-1]
        chosen[:] = chosen[order]
    for k in range(count):
        c = chosen[k]
        best = fixed + C[0, c] + C[c, 0]  # a new sortie of its own (always feasible: checked beforehand)
        best_r, best_after = -1, -1
        for r in range(info[0]):
            room = cap - pref[2, r, rlen[r] - 1]
            for p in range(rlen[r] - 1):
                if np.random.random() < blink:
                    continue
                a, b = routes[r, p], routes[r, p + 1]
                dc = C[a, c] + C[c, b] - C[a, b]
                if dc < best and E[a, c] + E[c, b] - E[a, b] <= room:
                    best, best_r, best_after = dc, r, p
        if best_r < 0:
            best_r = info[0]
            info[0] += 1
            routes[best_r, 0], routes[best_r, 1], routes[best_r, 2] = 0, c, 0
            rlen[best_r] = 3
        else:
            for t in range(rlen[best_r] - 1, best_after, -1):
                routes[best_r, t + 1] = routes[best_r, t]
            routes[best_r, best_after + 1] = c
            rlen[best_r] += 1
        refresh(best_r, routes, rlen, route_of, pos, pref, C, E)
        _touch(best_r, stamp, info)
        is_removed[c] = False


@cached_kernel
def seed_rng(seed):
    """Seed numba's own generator (separate from numpy's in Python)."""
    np.random.seed(seed)


@cached_kernel
def search(
    C, E, fixed, cap, neigh, adj,
    routes, rlen, info, route_of, pos, pref, stamp, tested, buf,
    cur_routes, cur_rlen, cur_info, best_routes, best_rlen, best_info, costs,
    iterations, temp_start, temp_end, mean_removed, max_string, blink, with_local_search,
):  # fmt: skip
    """``iterations`` rounds of ruin, recreate, local search and the simulated-annealing acceptance of SISR
    (accept when cost < current - T ln U, U uniform; T falls geometrically from temp_start to temp_end over
    the rounds). The working solution starts equal to the current one; costs = [current, best] is updated,
    and the best solution is copied whenever it improves."""
    n = C.shape[0]
    removed = np.empty(n, dtype=np.int64)
    is_removed = np.zeros(n, dtype=np.bool_)
    buoys = np.arange(1, n)
    for it in range(iterations):
        temperature = temp_start * (temp_end / temp_start) ** (it / max(1, iterations))
        count = ruin(buoys, adj, mean_removed, max_string, True, routes, rlen, info, route_of, pos, pref, stamp,
                     removed, is_removed, C, E)  # fmt: skip
        _recreate(count, blink, fixed, cap, routes, rlen, info, route_of, pos, pref, stamp, removed, is_removed, C, E)
        if with_local_search:
            local_search(C, E, fixed, cap, neigh, routes, rlen, info, route_of, pos, pref, stamp, tested, buf)
        cost = total_cost(pref, rlen, info, fixed)
        if cost < costs[0] - temperature * np.log(np.random.random()):
            copy_solution(routes, rlen, info, cur_routes, cur_rlen, cur_info)
            costs[0] = cost
            if cost < costs[1] - EPS:
                copy_solution(routes, rlen, info, best_routes, best_rlen, best_info)
                costs[1] = cost
        else:
            restore(cur_routes, cur_rlen, cur_info, routes, rlen, info, route_of, pos, pref, stamp, C, E)
