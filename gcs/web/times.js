// Times as an operator reads them: wall-clock in the browser's own time zone, durations in minutes and seconds,
// dates where a list spans days. The service stores ISO 8601 instants (created_at, updated_at, status events);
// vehicle-boot seconds stay in the technical figures (titles, the report).

const CLOCK = new Intl.DateTimeFormat(undefined, {
  hour: "2-digit",
  minute: "2-digit",
  second: "2-digit",
  hour12: false,
});
const DATE_TIME = new Intl.DateTimeFormat(undefined, {
  year: "numeric",
  month: "short",
  day: "numeric",
  hour: "2-digit",
  minute: "2-digit",
  hour12: false,
});

// a Date (or epoch ms) -> "14:03:05"
export function clockTime(date) {
  return CLOCK.format(date);
}

// an ISO 8601 instant -> "27 Nov 2026, 14:03" in the browser's zone ("–" when there is none or it is unreadable)
export function dateTime(iso) {
  const ms = iso ? Date.parse(iso) : NaN;
  return Number.isNaN(ms) ? "–" : DATE_TIME.format(ms);
}

// seconds -> "12 s", "3 min 05 s", "1 h 02 min" ("–" when unknown)
export function duration(seconds) {
  if (seconds == null || !Number.isFinite(Number(seconds))) return "–";
  const total = Math.round(Number(seconds));
  const h = Math.floor(total / 3600);
  const m = Math.floor((total % 3600) / 60);
  const s = total % 60;
  const pad = (n) => String(n).padStart(2, "0");
  if (h) return `${h} h ${pad(m)} min`;
  if (m) return `${m} min ${pad(s)} s`;
  return `${s} s`;
}

// The wall-clock instant (epoch ms) of vehicle time t_s (time_boot_ms / 1000) of a mission, or null when it cannot
// be told exactly. Exact only while the vehicle is on the boot the mission flew on: its boot instant (SYSTEM_TIME:
// unix time - boot time, the link's boot_instant_s) is known and no later than the mission's creation (a boot
// since, or a vehicle that never sent its clock, leaves vehicle times without an origin). The service stores no
// boot instant with the mission, so a mission flown on an earlier boot keeps its vehicle seconds.
export function vehicleInstant(t_s, mission, vehicle) {
  if (t_s == null || !mission || !vehicle || !vehicle.connected || vehicle.boot_instant_s == null) return null;
  const created = Date.parse(mission.created_at);
  const boot = vehicle.boot_instant_s * 1000;
  if (Number.isNaN(created) || boot > created) return null;
  return boot + t_s * 1000;
}
