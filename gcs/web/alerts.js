// Alerts: what the operator must notice, told three ways.
// - The event log (index.html #event-list, in the side panel): every event, newest first, with its wall-clock time
//   and severity: the vehicle's STATUSTEXTs by their MAV_SEVERITY, its mode changes, the link lost and back, the
//   watched mission's status changes, and the refusals the page shows (a Fly the service turned down). The last
//   EVENTS_KEPT are kept.
// - The banner across the top (#banner, in the sticky top block): a critical event (a STATUSTEXT of severity
//   CRITICAL or worse, a mission failed, the link lost) in plain words, its MAVLink detail one click away in a
//   <details>; it stays until dismissed, and a newer critical event replaces it (the count of others is shown); a
//   "Lost contact" banner goes by itself when contact is back.
// - A beep (WebAudio, no audio file) for each critical event, once the page has had a user gesture (browsers start
//   audio only after one), unless muted with the bar's sound toggle.
// Text from the vehicle or the service goes in as text only (textContent, h()).
import { byId, h } from "./dom.js";
import { MissionStatus } from "./status.js";
import { clockTime } from "./times.js";

export const EVENTS_KEPT = 500; // at least the last 200, as asked; a few KB of DOM

// MAV_SEVERITY by value, in plain words; CRITICAL (2) or worse alerts
export const SEVERITIES = ["emergency", "alert", "critical", "error", "warning", "notice", "info", "debug"];
const CRITICAL = 2;
const WARNING = 4;
export const Severity = Object.freeze({ critical: CRITICAL, error: 3, warning: WARNING, notice: 5, info: 6 });

const severityName = (severity) => SEVERITIES[severity] ?? `severity ${severity}`;

// ----- the sound
class Beeper {
  constructor(button) {
    this.button = button;
    this.context = null; // made on the first user gesture: before one, the browser keeps it suspended
    this.muted = localStorage.getItem("gcs.muted") === "1";
    this.beeps = 0;
    const unlock = () => {
      if (this.context === null && window.AudioContext) this.context = new AudioContext();
      if (this.context && this.context.state === "suspended") this.context.resume();
    };
    document.addEventListener("pointerdown", unlock, { capture: true });
    document.addEventListener("keydown", unlock, { capture: true });
    button.addEventListener("click", () => {
      this.muted = !this.muted;
      localStorage.setItem("gcs.muted", this.muted ? "1" : "0");
      this.label();
    });
    this.label();
  }

  label() {
    this.button.textContent = this.muted ? "Sound off" : "Sound on";
    this.button.setAttribute("aria-pressed", String(!this.muted));
    this.button.classList.toggle("muted", this.muted);
  }

  // Three short square-wave pips at 880 Hz: unlike any map or chart sound, audible over wind and a generator.
  beep() {
    if (this.muted || this.context === null || this.context.state !== "running") return;
    const ctx = this.context;
    const gain = ctx.createGain();
    gain.connect(ctx.destination);
    gain.gain.value = 0;
    const oscillator = ctx.createOscillator();
    oscillator.type = "square";
    oscillator.frequency.value = 880;
    oscillator.connect(gain);
    const start = ctx.currentTime + 0.01;
    for (let k = 0; k < 3; k += 1) {
      gain.gain.setValueAtTime(0.2, start + k * 0.25);
      gain.gain.setValueAtTime(0, start + k * 0.25 + 0.15);
    }
    oscillator.start(start);
    oscillator.stop(start + 0.8);
    this.beeps += 1;
    this.button.dataset.beeps = String(this.beeps); // what a test (or a curious operator) can read
  }
}

// ----- the banner
class Banner {
  constructor() {
    this.element = byId("banner");
    this.others = 0; // critical events since the one shown, not dismissed
    byId("banner-dismiss").addEventListener("click", () => this.dismiss());
  }

  show(event) {
    this.others = this.element.hidden ? 0 : this.others + 1;
    this.current = event;
    byId("banner-severity").textContent = severityName(event.severity);
    byId("banner-text").textContent = event.text;
    byId("banner-detail").textContent = event.detail || "no further detail";
    byId("banner-details").open = false;
    byId("banner-more").textContent = this.others ? `(+${this.others} earlier: see Events)` : "";
    this.element.hidden = false;
  }

  dismiss() {
    this.element.hidden = true;
    this.others = 0;
    this.current = null;
  }

  // What `event` warned of is over (contact is back): its banner goes, unless a later alert has taken its place.
  withdraw(event) {
    if (event && this.current === event && !this.element.hidden) this.dismiss();
  }
}

// ----- the log
export class EventLog {
  constructor() {
    this.list = byId("event-list");
    this.count = byId("event-count");
    this.banner = new Banner();
    this.beeper = new Beeper(byId("sound"));
    this.events = []; // newest first
    this.showEmpty();
  }

  showEmpty() {
    this.list.replaceChildren(h("li", { class: "hint", "data-testid": "events-empty" }, "no events yet"));
  }

  // event: {severity (MAV_SEVERITY), text (plain words), detail (the technical figure: optional), at (a Date;
  // null: before the page opened)}. Severity CRITICAL or worse raises the banner and beeps.
  // extra: kept with the event (fromVehicle, rawText: a vehicle's STATUSTEXT as it came)
  add({ severity, text, detail = "", at = new Date(), ...extra }) {
    const event = { severity, text, detail, at, ...extra };
    if (!this.events.length) this.list.replaceChildren();
    this.events.unshift(event);
    this.list.prepend(this.item(event));
    while (this.events.length > EVENTS_KEPT) {
      this.events.pop();
      this.list.lastElementChild.remove();
    }
    this.count.textContent = String(this.events.length);
    if (severity <= CRITICAL && at !== null) {
      this.banner.show(event);
      this.beeper.beep();
    }
    return event;
  }

  item(event) {
    const name = severityName(event.severity);
    const time = event.at
      ? h(
          "time",
          { datetime: event.at.toISOString(), class: "event-time", "data-testid": "event-time" },
          clockTime(event.at),
        )
      : h("span", { class: "event-time", "data-testid": "event-time", title: "before the page opened" }, "before");
    const attributes = { class: `event severity-${name}`, "data-testid": "event", "data-severity": name };
    if (event.detail) attributes.title = event.detail;
    return h(
      "li",
      attributes,
      time,
      " ",
      h("b", { class: "event-severity", "data-testid": "event-severity" }, name),
      " ",
      h("span", { class: "event-text", "data-testid": "event-text" }, event.text),
    );
  }

  // The vehicle's latest warnings (severity WARNING or worse) within `withinMs`, newest first: the cause a
  // refusal's MAV_RESULT does not carry ("PreArm: Battery below minimum" before "refused to arm").
  recentVehicleWarnings(withinMs = 60_000) {
    const since = Date.now() - withinMs;
    return this.events.filter((e) => e.fromVehicle && e.severity <= WARNING && e.at && e.at.getTime() >= since);
  }
}

// ----- what is watched: the live stream's vehicle, the watched mission
export class Watch {
  constructor(log) {
    this.log = log;
    this.vehicles = new Map(); // sysid (or "first") -> {connected, mode, heard}
    this.lost = new Map(); // sysid (or "first") -> its "Lost contact" event, until contact is back
    this.mission = null; // {id, status, command} of the watched mission last seen
    this.serviceLost = false;
  }

  // vehicle: the live stream's vehicle part; label: how the log names it ("vehicle 1")
  vehicle(vehicle, label) {
    const key = vehicle.sysid ?? "first";
    const seen = this.vehicles.get(key);
    const heard = vehicle.status_texts_heard ?? (vehicle.status_texts || []).length;
    const now = { connected: vehicle.connected, mode: vehicle.connected ? vehicle.mode : null, heard };
    this.vehicles.set(key, now);
    if (!seen) {
      // the page opens: what the vehicle said before is logged (marked "before"), but raises no banner
      this.vehicleTexts(vehicle, label, (vehicle.status_texts || []).length, null);
      return;
    }
    if (seen.connected && !vehicle.connected) {
      const age = vehicle.heartbeat_age_s == null ? "" : ` (no HEARTBEAT for ${vehicle.heartbeat_age_s.toFixed(1)} s)`;
      const lost = this.log.add({ severity: CRITICAL, text: `Lost contact with ${label}`, detail: `link lost${age}` });
      this.lost.set(key, lost);
    } else if (!seen.connected && vehicle.connected) {
      this.log.add({ severity: Severity.notice, text: `Contact with ${label} back`, detail: "HEARTBEAT heard again" });
      this.log.banner.withdraw(this.lost.get(key)); // the log keeps both
      this.lost.delete(key);
    }
    if (vehicle.connected && seen.mode && now.mode && seen.mode !== now.mode) {
      this.log.add({ severity: Severity.info, text: `${label}: mode ${seen.mode} → ${now.mode}` });
    }
    this.vehicleTexts(vehicle, label, Math.max(0, heard - seen.heard), new Date());
  }

  vehicleTexts(vehicle, label, count, at) {
    const texts = vehicle.status_texts || [];
    const severities = vehicle.status_severities || [];
    const first = Math.max(0, texts.length - count);
    for (let i = first; i < texts.length; i += 1) {
      const severity = severities[i] ?? Severity.info;
      this.log.add({
        severity,
        text: severity <= CRITICAL ? `${label} reports: ${texts[i]}` : `${label}: ${texts[i]}`,
        detail: `STATUSTEXT, MAV_SEVERITY_${severityName(severity).toUpperCase()} (${severity})`,
        at,
        fromVehicle: true,
        rawText: texts[i],
      });
    }
  }

  // The watched mission as shown (GET /missions/{id} or the live stream): a change of status or of operator
  // command is an event; a failure is critical, with the vehicle's own latest warning as its likely cause when the
  // reason does not already say it (a refusal's MAV_RESULT does not carry it). words: the status in plain words (controls.js statusWords).
  missionShown(mission, command, words) {
    const before = this.mission;
    this.mission = { id: mission.id, status: mission.status, command };
    if (!before || before.id !== mission.id) return; // a mission newly shown: no change seen yet
    if (before.status === mission.status && before.command === command) return;
    const detail = `status ${before.status} → ${mission.status}, operator command ${command ?? "none"}` +
      (mission.reason ? `; reason: ${mission.reason}` : "");
    if (mission.status === MissionStatus.failed) {
      // the reason may carry it already (the service puts what the vehicle said with its refusal in it)
      const [latest] = this.log.recentVehicleWarnings();
      const unsaid = latest && !(mission.reason || "").includes(latest.rawText);
      const cause = unsaid ? ` The vehicle said: "${latest.rawText}".` : "";
      this.log.add({ severity: CRITICAL, text: `${words}.${cause}`, detail });
      return;
    }
    const severity = mission.status === MissionStatus.aborted ? WARNING : Severity.notice;
    this.log.add({ severity, text: words, detail });
  }

  // The page's own connection to the service (/ws): a closed stream means what the page shows is going stale.
  serviceStream(open) {
    if (!open && !this.serviceLost) {
      this.serviceLost = true;
      this.log.add({ severity: WARNING, text: "Connection to the ground-control service lost: reconnecting" });
    } else if (open && this.serviceLost) {
      this.serviceLost = false;
      this.log.add({ severity: Severity.notice, text: "Connection to the ground-control service back" });
    }
  }
}
