// A request the page repeats: now and every periodMs while started, never while its tab is hidden (a hidden page
// needs nothing; shown again, it asks at once), its answer handed on only if no newer request was made and it was
// not stopped since it was sent: a slow answer overtaken by a newer one, or one arriving after stop(), is dropped.
// The alarms, the AtoNs and the register overlay each poll with one.
export class Poller {
  // request: () => a promise of the answer; onAnswer(answer, ...args): poll(...args)'s answer; onError(error):
  // its failure (the answer shown stays)
  constructor(request, onAnswer, onError, periodMs) {
    this.request = request;
    this.onAnswer = onAnswer;
    this.onError = onError;
    this.periodMs = periodMs;
    this.timer = null;
    this.seq = 0; // the latest request's number
    document.addEventListener("visibilitychange", () => {
      if (!document.hidden && this.running) this.poll(); // back to the tab: what it missed
    });
  }

  get running() {
    return this.timer !== null;
  }

  // Poll now (poll's args: the first answer's) and every periodMs from now.
  start(...args) {
    this.stop();
    this.timer = setInterval(() => {
      if (!document.hidden) this.poll();
    }, this.periodMs);
    this.poll(...args);
  }

  stop() {
    clearInterval(this.timer);
    this.timer = null;
    this.seq += 1; // an answer still in flight is not this poller's any more
  }

  async poll(...args) {
    const seq = ++this.seq;
    let answer;
    try {
      answer = await this.request();
    } catch (error) {
      if (seq === this.seq) this.onError(error);
      return;
    }
    if (seq === this.seq) this.onAnswer(answer, ...args);
  }
}
