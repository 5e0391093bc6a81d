"""The controller families on the paper's buoy-inspection mission: a paired Monte Carlo over seeds, flown in lockstep.

    .venv/bin/python -m bench.control                 # 30 seeds, 2 workers: table + bench/results/control.json
    .venv/bin/python -m bench.control --seeds 5 --paper-seeds 0 --no-figures --out /tmp/control.json  # a quick look

The controllers (flight.CONTROLLERS: the cascade ADRC, the paper-literal ADRC, the PID cascade, and PX4's defaults)
fly the same mission in the same air, seed by seed (a paired design), each family at its shipped design
(adrc_offboard/gains/design.json, chosen by `python -m bench.tune` with the same optimiser and flight budget for
every family), and the benchmark reports tracking, gust rejection, ESO accuracy, control effort and mixer saturation
with confidence intervals and paired tests against the ADRC; control.json's "headline" gives one line per controller.
The modules, in reading order:
- `scenario`: the mission, the wind, the gust timing, the turbulence and D terms; the hover mission of the
  step experiment;
- `flight`: the three controllers, one recorded lockstep flight (`fly`) and the lateral step (`step_response`);
- `metrics`: what is measured on a flight's per-tick series;
- `statistics`: mean and 95 % CI per controller, paired t-test and Wilcoxon signed-rank test across seeds;
- `figures`: the paper's Figures 6 (altitude, yaw, pitch, roll), 7 (all six ESOs), 10 and 11 (and the step
  responses) drawn from seed 0, and Fig. 9 for bench/paper_figures.py;
- `__main__`: the command line, the worker pool, the table and control.json.
"""

from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
RESULTS = REPO / "bench" / "results"
