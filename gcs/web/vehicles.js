// The service's vehicles (the /ws message's `vehicles`, as GET /vehicles lists them): each one named and shown with
// its link and battery in the panel's Vehicles list, and, with more than one, the choice of what Plan and Fly use:
// one vehicle (`vehicle`: its system id) or the fleet (`vehicles: "fleet"`: the buoys shared among them, each
// flying its share from its own home; Plan previews the sharing). A lone vehicle's service needs no choice: the
// list and the choice stay hidden and requests name no vehicle, as before.
import { vehicleName } from "./controls.js";
import { h } from "./dom.js";

const FLEET = "fleet";

function batteryText(vehicle) {
  const pct = vehicle.battery_remaining_pct;
  return pct == null ? "no battery report" : `battery ${Math.round(pct)} %`;
}

function linkText(vehicle) {
  if (!vehicle.connected) return "no contact";
  return vehicle.armed ? "armed" : "on the ground";
}

export class VehicleChoice {
  // section: the panel's Vehicles section (hidden with one vehicle); list: its <ol>; select: the choice;
  // onChange(): the choice changed (a plan made for another choice is no longer the page's)
  constructor(section, list, select, onChange) {
    this.section = section;
    this.list = list;
    this.select = select;
    this.known = ""; // the system ids the options were made for
    select.addEventListener("change", () => onChange());
  }

  // vehicles: the /ws message's, in the service's order (the first is the one a request naming none flies)
  show(vehicles) {
    const ids = vehicles.map((v) => v.sysid).filter((id) => id != null);
    this.section.hidden = ids.length < 2;
    this.list.replaceChildren(
      ...vehicles.map((v) =>
        h(
          "li",
          { "data-testid": "vehicle-row", "data-sysid": String(v.sysid ?? "") },
          h("b", {}, vehicleName(v)),
          `: ${linkText(v)} · ${batteryText(v)}`,
        ),
      ),
    );
    const key = ids.join(",");
    if (key === this.known) return;
    this.known = key;
    const chosen = this.select.value;
    const options = ids.map((id) => h("option", { value: String(id) }, `vehicle ${id}`));
    if (ids.length > 1) options.push(h("option", { value: FLEET }, `the fleet: all ${ids.length}, buoys shared`));
    this.select.replaceChildren(...options);
    if ([...this.select.options].some((o) => o.value === chosen)) this.select.value = chosen;
  }

  isFleet() {
    return !this.section.hidden && this.select.value === FLEET;
  }

  // What a plan or mission request adds: nothing with one vehicle; else the vehicle chosen, or the fleet.
  request() {
    if (this.section.hidden || !this.select.value) return {};
    return this.isFleet() ? { vehicles: FLEET } : { vehicle: Number(this.select.value) };
  }
}
