// What the page is looking at: the placed depot and buoys, the plan, and the mission being watched.
// Plain data; map.js draws it and app.js changes it.
import { isUnderway } from "./status.js";

export const state = {
  depot: null, // {lat, lon}
  buoys: [], // {id, lat, lon}; id null for a buoy placed by a click (the service names it B<index>)
  plan: null, // the POST /plans answer (or a mission, which carries the same route fields)
  missionId: null,
  mission: null, // the latest GET /missions/{id}
  progress: null, // the mission's progress, from the mission or, fresher, from the live stream
  firstBuoySeq: 2, // the mission item sequence number of the first buoy (after home and takeoff)
};

// The buoys may be edited unless the watched mission is on its way to or on the vehicle.
export function buoysEditable() {
  return !(state.missionId && state.mission && isUnderway(state.mission.status));
}

// How each buoy is drawn: its label (visiting rank when planned, else placing order) and whether the
// vehicle has visited it or is heading to it. Returns [{label, visited, current}] parallel to state.buoys.
export function buoyMarkings() {
  const order = state.plan ? state.plan.order : [];
  const visitRank = new Map(order.map((index, rank) => [index, rank]));
  const visited = new Set();
  let current = null;
  if (state.progress && state.plan) {
    for (const seq of state.progress.reached_seqs || []) {
      const rank = seq - state.firstBuoySeq;
      if (rank >= 0 && rank < order.length) visited.add(order[rank]);
    }
    const rank = (state.progress.current_seq ?? -1) - state.firstBuoySeq;
    if (rank >= 0 && rank < order.length) current = order[rank];
    // the vehicle sequences past an item only after reaching it
    order.slice(0, Math.max(0, rank)).forEach((index) => visited.add(index));
  }
  return state.buoys.map((_buoy, index) => ({
    label: visitRank.has(index) ? visitRank.get(index) + 1 : index + 1,
    visited: visited.has(index),
    current: !visited.has(index) && index === current,
  }));
}
