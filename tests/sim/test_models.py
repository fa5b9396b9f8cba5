"""The IIWA7 model and the salad scene, written here from public facts (no downloads)."""
import numpy as np
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant

from drake_skills.scenario.salad import TASKS
from drake_skills.sim.salad_robot import grasp_configuration
from drake_skills.sim.models import (FLANGE_FRAME, IIWA7_BASE_FRAME, IIWA7_HEIGHT, IIWA7_JOINT_LIMITS,
                                     IIWA7_JOINT_NAMES, IIWA7_TORQUE_LIMITS, IIWA7_VELOCITY_LIMITS,
                                     add_salad_scene, load_scene_config, make_iiwa7_plant, models_dir)


def test_iiwa7_has_seven_actuated_joints_with_datasheet_limits():
    plant = make_iiwa7_plant()
    assert plant.num_positions() == 7 and plant.num_actuators() == 7
    lower, upper = IIWA7_JOINT_LIMITS
    # the SDF holds 6 decimals
    np.testing.assert_allclose(plant.GetPositionLowerLimits(), lower, atol=1e-5)
    np.testing.assert_allclose(plant.GetPositionUpperLimits(), upper, atol=1e-5)
    np.testing.assert_allclose(plant.GetVelocityUpperLimits(), IIWA7_VELOCITY_LIMITS, atol=1e-5)
    np.testing.assert_allclose(plant.GetEffortUpperLimits(), IIWA7_TORQUE_LIMITS, atol=1e-9)
    for name in IIWA7_JOINT_NAMES:
        assert plant.HasJointNamed(name)
    for body in range(1, 8):  # links 1..7 carry mass
        assert plant.GetBodyByName(f"iiwa_link_{body}").default_mass() > 0


def test_flange_at_zero_stands_1_266_m_above_the_base():
    plant = make_iiwa7_plant()
    ctx = plant.CreateDefaultContext()
    plant.SetPositions(ctx, np.zeros(7))
    X_BE = plant.CalcRelativeTransform(ctx, plant.GetFrameByName(IIWA7_BASE_FRAME), plant.GetFrameByName(FLANGE_FRAME))
    assert abs(X_BE.translation()[2] - IIWA7_HEIGHT) < 0.01
    assert np.linalg.norm(X_BE.translation()[:2]) < 0.01


def test_models_are_local_files_and_never_drake_models():
    for f in models_dir().rglob("*"):
        if f.suffix in (".sdf", ".urdf", ".yaml", ".xml"):
            assert "drake_models" not in f.read_text(), f


def test_salad_scene_loads_with_every_object_of_the_config():
    plant = MultibodyPlant(time_step=1e-3)
    parser = Parser(plant)
    cfg = load_scene_config()
    models = add_salad_scene(plant, parser, cfg)  # with the robot
    plant.Finalize()
    assert plant.GetModelInstanceName(models["iiwa"]) == "iiwa7"
    names = {plant.GetModelInstanceName(plant.GetModelInstanceByName(n)) for n in cfg.objects}
    assert names == set(cfg.objects)
    assert plant.num_actuated_dofs() == 7


def test_ik_reaches_every_grasp_pose_within_1cm_and_5_degrees():
    cfg = load_scene_config()
    plant = make_iiwa7_plant(cfg.robot_base.transform())
    ctx = plant.CreateDefaultContext()
    lower, upper = IIWA7_JOINT_LIMITS
    assert set(cfg.tasks) == set(TASKS)
    for task in TASKS:
        q = grasp_configuration(task)
        assert ((q >= lower) & (q <= upper)).all(), task
        plant.SetPositions(ctx, q)
        X_WE = plant.CalcRelativeTransform(ctx, plant.world_frame(), plant.GetFrameByName(FLANGE_FRAME))
        X_goal = cfg.tasks[task].grasp.transform()
        assert np.linalg.norm(X_WE.translation() - X_goal.translation()) < 0.01, task
        angle = X_WE.rotation().InvertAndCompose(X_goal.rotation()).ToAngleAxis().angle()
        assert np.rad2deg(angle) < 5.0, task
