// The control bar at the top of the page (index.html #console): the watched mission's status in plain words, the
// vehicle's name, mode, armed state and charge, and the buttons Fly, Hold, Resume, Return, Land and Abort. It sits
// outside the side panel's scroll (style.css .top is sticky) so that control is in reach at any scroll position.
// A button is enabled only when its action applies to what the page shows; each consequential action (Fly arms and
// launches, Return, Land, Abort) is confirmed first in the page's dialog (confirm.js), naming what will happen.
// Hold and Resume are not asked about: Hold is the safe stop, and Resume only undoes a Hold or a Return.
// What each action does is app.js's (the requests); this module decides when it applies and asks.
import { confirmAction } from "./confirm.js";
import { byId } from "./dom.js";
import { isUnderway, MissionStatus } from "./status.js";

// The operator command in force on a flying mission (MissionOut progress.command): null while it flies its route.
export const Command = Object.freeze({ hold: "hold", return: "return", land: "land" });

// A service's reason stripped of its MAVLink names in parentheses ("the vehicle refused to arm
// (MAV_RESULT_DENIED)" -> "the vehicle refused to arm"): the plain part the operator reads; the whole reason
// stays one click away (the banner's details, the panel's technical status line).
export function plainReason(reason) {
  if (!reason) return "";
  return reason.replace(/\s*\((?:[A-Z][A-Z0-9]*_)+[A-Z0-9_]+\)/g, "").trim();
}

function visitedWords(mission, progress) {
  const p = progress || {};
  const buoys = p.buoys || mission.order.length;
  const sortie = p.sorties > 1 && p.sortie != null ? `, sortie ${p.sortie + 1} of ${p.sorties}` : "";
  return `${p.visited || 0} of ${buoys} buoys visited${sortie}`;
}

// The watched mission's status as the operator reads it: "Mission 3: flying, 2 of 4 buoys visited",
// "Mission 3: holding position", "Mission 3: failed: the vehicle refused to arm".
export function statusWords(mission, progress) {
  if (!mission) return "No mission";
  const command = (progress && progress.command) || null;
  const reason = plainReason(mission.reason);
  const because = reason ? `: ${reason}` : "";
  const head = `Mission ${mission.id}: `;
  switch (mission.status) {
    case MissionStatus.planned:
      return `${head}planned, not started`;
    case MissionStatus.uploading:
      return `${head}sending the route to the vehicle`;
    case MissionStatus.uploaded:
      return `${head}route on the vehicle, taking off`;
    case MissionStatus.flying:
      if (command === Command.hold) return `${head}holding position (${visitedWords(mission, progress)})`;
      if (command === Command.return) return `${head}returning home`;
      if (command === Command.land) return `${head}landing where it is`;
      return `${head}flying, ${visitedWords(mission, progress)}`;
    case MissionStatus.waiting_for_battery:
      return `${head}landed, waiting for a battery swap`;
    case MissionStatus.completed:
      return `${head}completed, ${visitedWords(mission, progress)}`;
    case MissionStatus.aborted:
      return `${head}aborted${because}`;
    case MissionStatus.failed:
      return `${head}failed${because}`;
    default:
      return `${head}${mission.status}`;
  }
}

// "vehicle 1 (ARDUPILOTMEGA QUADROTOR)": by its MAVLink system id, the autopilot and airframe it announced.
export function vehicleName(vehicle) {
  if (!vehicle || vehicle.sysid == null) return "the vehicle";
  const kind = [vehicle.autopilot, vehicle.vehicle_type].filter(Boolean).join(" ");
  return kind ? `vehicle ${vehicle.sysid} (${kind})` : `vehicle ${vehicle.sysid}`;
}

// "vehicle 1: AUTO, armed, battery 57 %"
function vehicleWords(vehicle) {
  if (!vehicle || !vehicle.connected) {
    return vehicle && vehicle.sysid != null ? `vehicle ${vehicle.sysid}: no contact` : "no vehicle";
  }
  const pct = vehicle.battery_remaining_pct;
  const charge = pct == null ? "no battery report" : `battery ${Math.round(pct)} %`;
  const armed = vehicle.armed ? "armed" : "disarmed";
  return `vehicle ${vehicle.sysid}: ${vehicle.mode ?? "mode unknown"}, ${armed}, ${charge}`;
}

// Which actions apply now. view: {mission, progress, buoyCount, busy (a plan or mission request in flight)}
export function applicable({ mission, progress, buoyCount, busy }) {
  const underway = Boolean(mission && isUnderway(mission.status));
  const flying = Boolean(mission && mission.status === MissionStatus.flying);
  const command = (progress && progress.command) || null;
  return {
    fly: buoyCount > 0 && !busy && !underway,
    hold: flying && (command === null || command === Command.return),
    resume: flying && (command === Command.hold || command === Command.return),
    return: flying && command !== Command.return && command !== Command.land,
    land: flying && command !== Command.land,
    abort: underway,
  };
}

const BUTTONS = ["fly", "hold", "resume", "return", "land", "abort"];

export class ControlBar {
  // actions: {fly, hold, resume, return, land, abort}: each an async function doing the request (called once
  // confirmed); describe(): {vehicle: its name, connected, buoyCount, altitude_m} for the questions' texts
  constructor(actions, describe) {
    this.actions = actions;
    this.describe = describe;
    this.view = { mission: null, progress: null, buoyCount: 0, busy: false };
    for (const name of BUTTONS) byId(name).addEventListener("click", () => this.run(name));
  }

  // The question asked before a consequential action (null: asked nothing).
  question(name) {
    const { mission } = this.view;
    const about = this.describe();
    const id = mission ? mission.id : "";
    switch (name) {
      case "fly":
        return {
          title: "Fly the mission?",
          text:
            `${about.vehicle} arms and takes off at once to visit ${about.buoyCount} ` +
            `${about.buoyCount === 1 ? "buoy" : "buoys"} at ${about.altitude_m} m, then returns home.`,
          warning: about.connected ? "" : "No vehicle is in contact: the mission will fail to start.",
          confirm: "Arm and take off",
        };
      case "return":
        return {
          title: `Return mission ${id} home?`,
          text: `${about.vehicle} leaves its route, flies back home and lands there. Resume goes on with the route.`,
          confirm: "Return home",
        };
      case "land":
        return {
          title: `Land here?`,
          text: `${about.vehicle} leaves its route and lands where it is now, not at home.`,
          warning: "Where it is may be over water: it lands there all the same.",
          confirm: "Land here",
        };
      case "abort":
        return {
          title: `Abort mission ${id}?`,
          text: `Mission ${id} ends for good: ${about.vehicle} returns home and lands; it cannot be resumed.`,
          confirm: "Abort mission",
        };
      default:
        return null;
    }
  }

  async run(name) {
    const question = this.question(name);
    if (question && !(await confirmAction(question))) {
      this.say(`${name}: cancelled`, true);
      return;
    }
    this.say("");
    await this.actions[name]();
  }

  // view: what the page shows now ({mission, progress, buoyCount, busy}); vehicle: the mission's vehicle (the
  // live stream's), or null before the first message
  show(view, vehicle) {
    this.view = view;
    byId("console-status").textContent = statusWords(view.mission, view.progress);
    const failed = view.mission && [MissionStatus.failed, MissionStatus.aborted].includes(view.mission.status);
    byId("console-status").classList.toggle("bad", Boolean(failed));
    byId("console-status").title = view.mission && view.mission.reason ? view.mission.reason : "";
    if (vehicle !== undefined) byId("console-vehicle").textContent = vehicleWords(vehicle);
    const enabled = applicable(view);
    for (const name of BUTTONS) byId(name).disabled = !enabled[name];
  }

  // The outcome of the latest action, beside the buttons: an error (red) or, with ok, a note.
  say(text, ok = false) {
    byId("console-message").textContent = text;
    byId("console-message").classList.toggle("ok", ok);
  }
}
