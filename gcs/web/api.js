// The one place the page talks to the gcs service: every REST call, the file links and the /ws live stream.
// Errors come back as ApiError whose message is plain text (the page shows it with textContent).

export class ApiError extends Error {}

// The service answers every error as {detail: [{type, loc, msg}, ...]} (loc: ["body", "buoys", 3], or [] for
// the request as a whole); anything else (a proxy's page) is shown as it came.
function errorMessage(response, data, text) {
  const detail = data && data.detail;
  const where = (e) => (e.loc.length > 1 ? `${e.loc.slice(1).join(".")}: ` : "");
  if (Array.isArray(detail)) return detail.map((e) => `${where(e)}${e.msg}`).join("\n");
  if (typeof detail === "string") return detail;
  return text || response.statusText;
}

function parseJson(text) {
  try {
    return JSON.parse(text);
  } catch {
    return null; // e.g. a proxy's plain-text error page
  }
}

export class GcsApi {
  // token: () => the bearer token typed into the page ("" when the service needs none)
  constructor(token) {
    this.token = token;
  }

  async request(method, path, body, contentType = "application/json") {
    const headers = {};
    const token = this.token();
    if (token) headers.Authorization = `Bearer ${token}`;
    if (body !== undefined) headers["Content-Type"] = contentType;
    const payload = body === undefined || contentType !== "application/json" ? body : JSON.stringify(body);
    let response;
    try {
      response = await fetch(path, { method, headers, body: payload });
    } catch (error) {
      throw new ApiError(`the service is unreachable (${error.message})`); // fetch rejects only on network errors
    }
    const text = await response.text();
    const data = text ? parseJson(text) : null;
    if (!response.ok) throw new ApiError(`${response.status}: ${errorMessage(response, data, text)}`);
    return data;
  }

  openApi() {
    return this.request("GET", "/openapi.json");
  }

  vehicle() {
    return this.request("GET", "/vehicle");
  }

  plan(flightRequest) {
    return this.request("POST", "/plans", flightRequest);
  }

  createMission(flightRequest) {
    return this.request("POST", "/missions", { ...flightRequest, start: true });
  }

  mission(id) {
    return this.request("GET", `/missions/${encodeURIComponent(id)}`);
  }

  // the operator's word that a charged pack is in (the first vehicle, or one of the fleet by its system id)
  swapBattery(sysid = null) {
    const path = sysid == null ? "/vehicle/battery-swap" : `/vehicles/${encodeURIComponent(sysid)}/battery-swap`;
    return this.request("POST", path);
  }

  abortMission(id) {
    return this.request("POST", `/missions/${encodeURIComponent(id)}/abort`);
  }

  // The operator's commands to a mission in flight, each answering the mission (MissionOut), whose
  // progress.command then names the command in force ("hold", "return", "land"; null once resumed). Hold: stop
  // and hold position; resume: go on with the route after a hold or a return; return: fly home and land there;
  // land: land where the vehicle is.
  holdMission(id) {
    return this.request("POST", `/missions/${encodeURIComponent(id)}/hold`);
  }

  resumeMission(id) {
    return this.request("POST", `/missions/${encodeURIComponent(id)}/resume`);
  }

  returnMission(id) {
    return this.request("POST", `/missions/${encodeURIComponent(id)}/return`);
  }

  landMission(id) {
    return this.request("POST", `/missions/${encodeURIComponent(id)}/land`);
  }

  missions(limit = 50) {
    return this.request("GET", `/missions?limit=${limit}`);
  }

  // The flown track cut down for display (GET /missions/{id}/track): {points: [[lat, lon], ...], series: the
  // samples for the charts, tolerance_m}; /telemetry and track.geojson keep every sample.
  track(id, maxPoints = 2000) {
    return this.request("GET", `/missions/${encodeURIComponent(id)}/track?max_points=${maxPoints}`);
  }

  // file: a File from <input type=file>: GeoJSON or CSV (told apart by its name, as the service does), or an S-57
  // chart cell (.000), sent as its bytes (as text its binary records would be spoilt)
  async importBuoys(file) {
    const name = file.name.toLowerCase();
    const path = `/imports?filename=${encodeURIComponent(file.name)}`;
    if (name.endsWith(".000")) return this.request("POST", path, file, "application/octet-stream");
    const type = name.endsWith(".csv") ? "text/csv" : "application/geo+json";
    return this.request("POST", path, await file.text(), type);
  }

  // Each buoy's inspection record so far (GET /missions/{id}/inspections: InspectionOut, by input index): verdict,
  // findings, light read, the frames' URLs (GET /missions/{id}/frames/{frame}) and the best one's.
  inspections(id) {
    return this.request("GET", `/missions/${encodeURIComponent(id)}/inspections`);
  }

  // The offline base map (GET /basemap.geojson): a FeatureCollection of the imported cells' land, piers and depth
  // contours (properties.layer, a contour's depth_m); empty before a cell is imported.
  basemap() {
    return this.request("GET", "/basemap.geojson");
  }

  // The AIS feed's AtoNs (GET /ais/atons: AtonsOut): each one's latest report, its age and flags.
  atons() {
    return this.request("GET", "/ais/atons");
  }

  // The register's buoys (GET /buoys: BuoyOut), filtered by {bbox: "W,S,E,N", kind, overdue_days, open_defects}
  // (a filter left out or null: not filtered on).
  buoys(filters = {}) {
    const query = new URLSearchParams();
    for (const [name, value] of Object.entries(filters)) if (value != null) query.set(name, String(value));
    const text = query.toString();
    return this.request("GET", text ? `/buoys?${text}` : "/buoys");
  }

  // One register buoy (GET /buoys/{id}: BuoyDetailOut): its defects, its history (oldest first), its AtoN.
  buoy(id) {
    return this.request("GET", `/buoys/${encodeURIComponent(id)}`);
  }

  // The register's off-station alarms (GET /alarms: AlarmOut), each with its evidence: an inspection's (its
  // mission, the distance seen) or the AIS feed's (the AtoN's report), and why.
  alarms() {
    return this.request("GET", "/alarms");
  }

  // name: track.geojson, plan, waypoints, report, inspections.csv or inspections.geojson
  missionFileUrl(id, name) {
    return `/missions/${encodeURIComponent(id)}/${name}`;
  }

  // The /ws subprotocols: with a token typed, the token itself (base64url), since a browser cannot set an
  // Authorization header on a WebSocket and a ?token= would land in access logs. The service answers
  // "buoy-gcs.live" and never echoes the token back.
  liveProtocols() {
    const token = this.token();
    if (!token) return [];
    const binary = String.fromCharCode(...new TextEncoder().encode(token));
    const base64url = btoa(binary).replace(/\+/g, "-").replace(/\//g, "_").replace(/=+$/, "");
    return ["buoy-gcs.live", `bearer.${base64url}`];
  }

  // Calls onMessage with every decoded /ws message; reconnects a second after the stream closes (with the
  // token as typed by then: a service with a token refuses the stream until the token is given). onState(open):
  // true at the first message of each connection, false when one that had delivered a message closes.
  openLiveStream(onMessage, onState = () => {}) {
    const connect = () => {
      const url = `${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/ws`;
      const ws = new WebSocket(url, this.liveProtocols());
      let delivered = false;
      ws.onmessage = (event) => {
        if (!delivered) onState(true);
        delivered = true;
        onMessage(JSON.parse(event.data));
      };
      ws.onclose = () => {
        if (delivered) onState(false);
        setTimeout(connect, 1000);
      };
    };
    connect();
  }
}
