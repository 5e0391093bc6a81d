// What the page is looking at: the placed depot and buoys, the plan, and the mission being watched with its
// inspection records. Plain data; map.js draws it and app.js changes it.
import { sortieOfBuoy } from "./sorties.js";
import { isUnderway } from "./status.js";

export const state = {
  depot: null, // {lat, lon}
  buoys: [], // {id, lat, lon}; id null for a buoy placed by a click (the service names it B<index>)
  plan: null, // the POST /plans answer (or a mission, which carries the same route fields)
  missionId: null,
  mission: null, // the latest GET /missions/{id}
  progress: null, // the mission's progress, from the mission or, fresher, from the live stream
  firstBuoySeq: 2, // the mission item sequence number of the first buoy (after home and takeoff)
  inspections: new Map(), // the watched mission's inspection records (InspectionOut) by buoy input index
  inspectionsSeq: 0, // bumped whenever the records change
  busy: false, // a plan or mission request in flight (Plan and Fly wait for it)
};

// The buoys may be edited unless the watched mission is on its way to or on the vehicle.
export function buoysEditable() {
  return !(state.missionId && state.mission && isUnderway(state.mission.status));
}

// The buoys the vehicle has visited and the one it heads for. The progress counts the items of the sortie on
// board (its seqs from that sortie's first buoy); the buoys of earlier sorties come from the live stream's
// visited_buoys and the mission's buoy_results.
function visitedAndCurrent(plan, progress) {
  const visited = new Set(progress.visited_buoys || []);
  const results = (state.mission && state.mission.buoy_results) || [];
  results.filter((b) => b.reached).forEach((b) => visited.add(b.index));
  if (plan.fleet) return { visited, current: null }; // each vehicle's sequence numbers count its own part mission
  const onBoard = progress.sortie ?? 0;
  const order = plan.sorties.length > onBoard ? plan.sorties[onBoard].order : plan.order;
  for (const seq of progress.reached_seqs || []) {
    const rank = seq - state.firstBuoySeq;
    if (rank >= 0 && rank < order.length) visited.add(order[rank]);
  }
  const rank = (progress.current_seq ?? -1) - state.firstBuoySeq;
  // the vehicle sequences past an item only after reaching it
  order.slice(0, Math.max(0, rank)).forEach((index) => visited.add(index));
  const current = rank >= 0 && rank < order.length ? order[rank] : null;
  return { visited, current };
}

// Whether the map shows the watched mission's own plan (not a plan made since, which has no id and has not flown).
const showsWatchedMission = () => Boolean(state.plan && state.plan.id != null && state.plan.id === state.missionId);

// A buoy's verdict on the watched mission: its record's, "pending" while the mission is under way and the buoy not
// judged yet, else null (nothing to show: the mission ended without a record of it).
function verdictOf(index) {
  const record = state.inspections.get(index);
  if (record) return record.verdict;
  return state.mission && isUnderway(state.mission.status) ? "pending" : null;
}

// How each buoy is drawn: its label (visiting rank when planned, else placing order), whether the vehicle has
// visited it or is heading to it, its sortie (0-based; null for a single tour, whose buoys keep their look) and its
// inspection's verdict (null: none to show). Returns [{label, visited, current, sortie, verdict}] parallel to
// state.buoys.
export function buoyMarkings() {
  const order = state.plan ? state.plan.order : [];
  const visitRank = new Map(order.map((index, rank) => [index, rank]));
  const sortieOf = sortieOfBuoy(state.plan);
  const flown = showsWatchedMission() && state.progress; // progress only on the watched mission's own plan
  const { visited, current } = flown ? visitedAndCurrent(state.plan, state.progress) : { visited: new Set() };
  const judged = showsWatchedMission();
  return state.buoys.map((_buoy, index) => ({
    label: visitRank.has(index) ? visitRank.get(index) + 1 : index + 1,
    visited: visited.has(index),
    current: !visited.has(index) && index === current,
    sortie: sortieOf.get(index) ?? null,
    verdict: judged ? verdictOf(index) : null,
  }));
}

// The buoys with a verdict to show, as the inspection list and the gallery take them, in visiting order:
// [{index, id, label, verdict, record, arrival_s, arrival_at}] (record null while pending; arrival_s: the vehicle
// time it was reached, arrival_at: when the service heard it (ISO, UTC); null while not).
export function inspectionRows(markings = buoyMarkings()) {
  const results = (state.mission && state.mission.buoy_results) || [];
  const arrivals = new Map(results.map((b) => [b.index, b]));
  return state.buoys
    .map((buoy, index) => ({
      index,
      id: buoy.id,
      label: markings[index].label,
      verdict: markings[index].verdict,
      record: state.inspections.get(index) ?? null,
      arrival_s: arrivals.get(index)?.arrival_s ?? null,
      arrival_at: arrivals.get(index)?.arrival_at ?? null,
    }))
    .filter((row) => row.verdict != null)
    .sort((a, b) => a.label - b.label);
}
