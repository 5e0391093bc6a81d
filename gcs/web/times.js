// Times as an operator reads them: wall-clock in the browser's own time zone, durations in minutes and seconds,
// dates where a list spans days. The service stores ISO 8601 instants (created_at, updated_at, status events);
// vehicle-boot seconds stay in the technical figures (titles, the report).

const CLOCK = new Intl.DateTimeFormat(undefined, { hour: "2-digit", minute: "2-digit", second: "2-digit", hour12: false });
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
