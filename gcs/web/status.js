// The mission states, as the service defines them: the page carries no list of its own. At start app.js
// hands the service's OpenAPI document to defineMissionStatus (components.schemas.MissionStatus.enum, the
// pydantic str enum); code then writes MissionStatus.flying etc. Reading a name the service does not define
// throws, so a rename on the server breaks loudly instead of silently never matching.
// (tests/test_web_statuses.py checks every MissionStatus.<name> in these sources against the server's enum.)

let statuses = null; // frozen {name: value} once defined

export function defineMissionStatus(openApi) {
  const values = openApi?.components?.schemas?.MissionStatus?.enum;
  if (!Array.isArray(values) || !values.length) throw new Error("the service's OpenAPI has no MissionStatus enum");
  statuses = Object.freeze(Object.fromEntries(values.map((value) => [value, value])));
}

export const MissionStatus = new Proxy(
  {},
  {
    get(_target, name) {
      if (typeof name !== "string") return undefined; // e.g. Symbol.toStringTag from a console
      if (statuses === null) throw new Error(`MissionStatus.${name} read before the service's statuses were loaded`);
      if (!Object.hasOwn(statuses, name)) throw new Error(`unknown MissionStatus.${name}`);
      return statuses[name];
    },
    set() {
      throw new TypeError("MissionStatus is read-only");
    },
    defineProperty() {
      throw new TypeError("MissionStatus is read-only");
    },
    deleteProperty() {
      throw new TypeError("MissionStatus is read-only");
    },
  },
);

// On the way to or on the vehicle: the route is fixed (the page does not edit buoys then).
export function isUnderway(status) {
  return [
    MissionStatus.uploading,
    MissionStatus.uploaded,
    MissionStatus.flying,
    MissionStatus.waiting_for_battery,
  ].includes(status);
}

// Ended for good: nothing about the mission changes any more.
export function isFinished(status) {
  return [MissionStatus.completed, MissionStatus.aborted, MissionStatus.failed].includes(status);
}
