"""The wrist message: lcmt_drake_signal with three named values in metres and a millisecond timestamp."""
import numpy as np
import pytest
from drake import lcmt_drake_signal

from drake_skills.systems.wrist_receiver import WristSignalReceiver, wrist_from_message
from drake_skills.systems.wrist_sender import WRIST_COORDS, WristSignalSender, wrist_message


def test_a_wrist_message_round_trips_through_its_bytes():
    p = np.array([0.31, -0.42, 1.05])
    msg = lcmt_drake_signal.decode(wrist_message(p, 12.3456).encode())
    assert msg.dim == 3 and tuple(msg.coord) == WRIST_COORDS and msg.timestamp == 12346
    q, t = wrist_from_message(msg)
    np.testing.assert_array_equal(q, p)
    assert t == pytest.approx(12.346)


def test_a_message_that_is_not_a_wrist_is_refused_naming_the_channel():
    with pytest.raises(RuntimeError, match="no wrist message received on 'W'"):
        wrist_from_message(lcmt_drake_signal(), channel="W")
    other = wrist_message(np.zeros(3), 1.0)
    other.coord = ["x", "y", "z"]
    with pytest.raises(ValueError, match="'W'.*names its values"):
        wrist_from_message(other, channel="W")
    short = lcmt_drake_signal()
    short.dim, short.val, short.coord, short.timestamp = 2, [0.0, 1.0], ["a", "b"], 5
    with pytest.raises(ValueError, match="dim 3"):
        wrist_from_message(short, channel="W")
    bad = wrist_message(np.zeros(3), 1.0)
    bad.val = [0.0, float("nan"), 0.0]
    with pytest.raises(ValueError, match="not finite"):
        wrist_from_message(bad, channel="W")
    with pytest.raises(ValueError, match="3 finite"):
        wrist_message([0.0, 1.0], 0.0)


def test_sender_and_receiver_systems_carry_the_position():
    sender, receiver = WristSignalSender(), WristSignalReceiver(channel="W")
    sctx, rctx = sender.CreateDefaultContext(), receiver.CreateDefaultContext()
    sctx.SetTime(2.0)
    sender.GetInputPort("human_wrist").FixValue(sctx, [0.1, 0.2, 0.3])
    msg = sender.GetOutputPort("lcmt_drake_signal").Eval(sctx)
    receiver.GetInputPort("lcmt_drake_signal").FixValue(rctx, msg)
    np.testing.assert_allclose(receiver.GetOutputPort("human_wrist").Eval(rctx), [0.1, 0.2, 0.3])
    assert receiver.GetOutputPort("wrist_time").Eval(rctx)[0] == 2.0
