"""receive_first_messages: control starts only on a status with finite joint positions (memq, a minimal diagram)."""
from types import SimpleNamespace

import numpy as np
import pytest
from drake import lcmt_drake_signal, lcmt_iiwa_status
from pydrake.lcm import DrakeLcm
from pydrake.manipulation import IiwaStatusReceiver
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource
from pydrake.systems.lcm import LcmInterfaceSystem, LcmSubscriberSystem
from drake_skills.sim.lcm_controller import receive_first_messages
from drake_skills.sim.models import HOME_Q, IIWA7_JOINT_LIMITS, IIWA7_VELOCITY_LIMITS
from drake_skills.systems.iiwa_guard import GuardLimits, IiwaCommandGuard


def _status(q, utime):
    m = lcmt_iiwa_status()
    m.utime, m.num_joints = utime, 7
    m.joint_position_measured, m.joint_velocity_estimated = list(q), [0.0] * 7
    for f in ("joint_position_commanded", "joint_position_ipo", "joint_torque_measured", "joint_torque_commanded",
              "joint_torque_external"):
        setattr(m, f, [0.0] * 7)
    return m


def _build():
    lcm = DrakeLcm("memq://")
    b = DiagramBuilder()
    b.AddSystem(LcmInterfaceSystem(lcm))
    ss = b.AddSystem(LcmSubscriberSystem.Make("IIWA_STATUS", lcmt_iiwa_status, lcm, use_cpp_serializer=True))
    rx = b.AddSystem(IiwaStatusReceiver())
    ws = b.AddSystem(LcmSubscriberSystem.Make("WRIST", lcmt_drake_signal, lcm))
    g = b.AddSystem(IiwaCommandGuard(GuardLimits(*IIWA7_JOINT_LIMITS, IIWA7_VELOCITY_LIMITS, period=0.005)))
    b.Connect(ss.get_output_port(), rx.get_input_port())
    for p in ("position_measured", "velocity_estimated"):
        b.Connect(rx.GetOutputPort(p), g.GetInputPort(p))
    b.Connect(rx.GetOutputPort("time_measured"), g.GetInputPort("status_time"))
    b.Connect(b.AddSystem(ConstantVectorSource(np.concatenate([HOME_Q, np.zeros(7)]))).get_output_port(),
              g.GetInputPort("desired_state"))
    d = b.Build()
    h = SimpleNamespace(subscribers=[ss, ws], subscribed=(("IIWA_STATUS", "lcmt_iiwa_status"),
                                                          ("WRIST", "lcmt_drake_signal")), lcm=lcm, guard=g)
    return d, h, lcm


def _wrist():
    m = lcmt_drake_signal()
    m.dim, m.val, m.coord, m.timestamp = 1, [0.0], ["x"], 1
    return m



def test_nan_statuses_only_time_out_naming_the_status_channel():
    # a cold review found a NaN first status killing control with a message about zeros
    d, h, lcm = _build()
    sim = Simulator(d)
    lcm.Publish("IIWA_STATUS", _status(np.full(7, np.nan), 1000).encode())
    lcm.Publish("WRIST", _wrist().encode())
    with pytest.raises(TimeoutError, match="no status with finite joint positions within 0.3 s on 'IIWA_STATUS'"):
        receive_first_messages(h, sim.get_mutable_context(), 0.3)


def test_a_good_status_after_a_nan_one_starts_the_controller_there():
    d, h, lcm = _build()
    sim = Simulator(d)
    lcm.Publish("IIWA_STATUS", _status(np.full(7, np.nan), 1000).encode())
    lcm.Publish("WRIST", _wrist().encode())
    lcm.Publish("IIWA_STATUS", _status(HOME_Q, 2000).encode())
    receive_first_messages(h, sim.get_mutable_context(), 5.0)
    sim.Initialize()
    g = h.guard
    np.testing.assert_allclose(g.guard_state(g.GetMyContextFromRoot(sim.get_context())).command, HOME_Q)
