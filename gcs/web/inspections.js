// The watched mission's inspection records, fetched when asked: at once when a mission is opened, then on each
// change of its progress, at most once a MIN_INTERVAL_MS (changes in between are folded into one fetch after it).
// Only an answer for the mission still watched is handed on; a fetch that fails is said and tried again on the
// next change.
const MIN_INTERVAL_MS = 1000;

export class InspectionFeed {
  // fetchRecords(missionId) -> Promise of the records; onRecords(missionId, records); onError(error)
  constructor(fetchRecords, onRecords, onError) {
    this.fetchRecords = fetchRecords;
    this.onRecords = onRecords;
    this.onError = onError;
    this.missionId = null;
    this.wanted = false; // a change since the last fetch started
    this.inFlight = false;
    this.timer = null;
    this.lastStart = -Infinity;
  }

  // Watch mission `missionId` (null: none) and fetch its records now (or as soon as the fetch in flight ends).
  watch(missionId) {
    this.missionId = missionId;
    this.lastStart = -Infinity;
    if (this.timer !== null) {
      clearTimeout(this.timer);
      this.timer = null;
    }
    this.refresh();
  }

  // Something changed (the progress, the mission): fetch again, within the rate.
  refresh() {
    if (this.missionId == null) return;
    this.wanted = true;
    if (this.inFlight || this.timer !== null) return;
    const wait = this.lastStart + MIN_INTERVAL_MS - performance.now();
    if (wait <= 0) this.fetchNow();
    else
      this.timer = setTimeout(() => {
        this.timer = null;
        this.fetchNow();
      }, wait);
  }

  async fetchNow() {
    const id = this.missionId;
    if (!this.wanted || id == null) return;
    this.wanted = false;
    this.inFlight = true;
    this.lastStart = performance.now();
    try {
      const records = await this.fetchRecords(id);
      if (id === this.missionId) this.onRecords(id, records);
    } catch (error) {
      if (id === this.missionId) this.onError(error);
    } finally {
      this.inFlight = false;
      if (this.wanted) this.refresh();
    }
  }
}
