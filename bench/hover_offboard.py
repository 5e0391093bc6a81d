"""A minimal outer-loop controller for the lockstep benchmark: a PD law on position, through the same node.

.venv/bin/python -m bench.hover_offboard --connect udpout:127.0.0.1:14540 [--no-engage]
"""

from __future__ import annotations

from adrc_offboard.cli import build_parser
from adrc_offboard.node import OffboardNode
from uavcore.airframe import Airframe
from uavcore.rotation import acceleration_to_attitude


class PositionPd:
    """a = a_ref + kp (p_ref - p) + kd (v_ref - v): the smallest outer loop that flies."""

    def __init__(self, kp: float = 1.5, kd: float = 2.0) -> None:
        self.kp, self.kd = kp, kd
        self.airframe = Airframe.table2()

    def reset(self) -> None:
        pass

    def update(self, setpoint, estimate, dt):
        acc = (
            setpoint.acceleration
            + self.kp * (setpoint.position - estimate.position)
            + self.kd * (setpoint.velocity - estimate.velocity)
        )
        af = self.airframe
        return acceleration_to_attitude(acc, setpoint.yaw, af.mass, af.g, af.max_thrust_n)

    def disturbance_estimates(self) -> dict:
        return {}


def main() -> None:
    args = build_parser().parse_args()
    OffboardNode(PositionPd(), args.connect, args.rate, args.engage).run(args.duration)


if __name__ == "__main__":
    main()
