"""contract.py: a controller is checked against the contract before it is wired, each refusal
naming the port; a scenario's controller name resolves only to what the user registered.
(Entry-point plugins: test_untrusted_input.py; controllers wired into a run: test_station.py.)"""

import numpy as np
import pytest
from pydrake.systems.framework import LeafSystem

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.control import contract
from stewart_drake.control.contract import (
    LQI_STATUS_NAMES,
    ControllerContext,
    UserController,
    check_controller,
    register_controller,
    resolve_controller,
)
from stewart_drake.control.lqi.controller import LqiDiagram
from stewart_drake.control.lqi.driver import LqiDriver
from stewart_drake.control.pd import CrankPdController
from stewart_drake.robot.geometry import X_HOME


def _system(inputs=(("x_d", 18),), outputs=(("T", 6),), status_names=None, name=""):
    system = LeafSystem()
    if name:
        system.set_name(name)
    for port, size in inputs:
        system.DeclareVectorInputPort(port, size)
    for port, size in outputs:
        system.DeclareVectorOutputPort(port, size, lambda context, out: out.SetZero())
    if status_names is not None:
        system.status_names = status_names
    return system


def test_the_smallest_controller_passes_and_the_package_s_controllers_do(geometry):
    check_controller(_system())
    check_controller(CrankPdController(geometry))
    lqi = LqiDiagram(geometry, LqiDriver())
    check_controller(lqi)
    assert tuple(lqi.status_names) == LQI_STATUS_NAMES


@pytest.mark.parametrize(
    "system, says",
    [
        (lambda: _system(inputs=()), r"controller mine has no input port 'x_d' \(required"),
        (lambda: _system(outputs=()), r"controller mine has no output port 'T' \(required"),
        (
            lambda: _system(inputs=(("x_d", 18), ("pose", 6))),
            r"controller mine declares input port 'pose', which the Diagram cannot connect; the "
            r"contract's inputs are \['T_ff', 'motor_angle'",
        ),
        (
            lambda: _system(inputs=(("x_d", 12),)),
            r"controller mine: input port 'x_d' has size 12, the contract says 18",
        ),
        (
            lambda: _system(outputs=(("T", 6), ("e_bar", 3))),
            r"controller mine: output port 'e_bar' has size 3, the contract says 6",
        ),
        (
            lambda: _system(outputs=(("T", 6), ("status", 2))),
            r"controller mine has a status output of size 2; give it a status_names attribute",
        ),
        (
            lambda: _system(outputs=(("T", 6), ("status", 2)), status_names=("a",)),
            "status output of size 2",
        ),
    ],
)
def test_a_controller_breaking_the_contract_is_refused_naming_the_port(system, says):
    s = system()
    s.set_name("mine")
    with pytest.raises(InvalidConfigError, match=says):
        check_controller(s)


def test_a_status_with_its_names_and_any_size_passes():
    check_controller(_system(outputs=(("T", 6), ("status", 3)), status_names=("a", "b", "c")))


def test_a_factory_that_returns_something_else_is_refused():
    with pytest.raises(InvalidConfigError, match="must return a pydrake LeafSystem .*got dict"):
        check_controller({"T": np.zeros(6)})


def test_a_user_controller_resolves_only_a_registered_name(monkeypatch, geometry):
    monkeypatch.setattr(contract, "CONTROLLER_REGISTRY", {})
    with pytest.raises(
        InvalidConfigError,
        match=r"'mypkg.ctl:make' is an import path, and a "
        r"scenario never imports code; .*registered: "
        r"none",
    ):
        resolve_controller("mypkg.ctl:make")
    made = []

    def factory(context, gain=1.0):
        made.append((context, gain))
        return _system()

    register_controller("mine", factory)
    assert resolve_controller("mine") is factory
    driver = UserController(factory="mine", parameters={"gain": 2.5}).validate(1e-3)
    context = ControllerContext(geometry, 1e-3, 5e-4, 1e-3, X_HOME)
    check_controller(driver.make(context))
    assert made == [(context, 2.5)]
    with pytest.raises(InvalidConfigError, match="registered: mine"):
        resolve_controller("yours")
    with pytest.raises(InvalidConfigError, match="controller.parameters.gain must be a number"):
        UserController(factory="mine", parameters={"gain": "high"}).validate(1e-3)
    with pytest.raises(InvalidConfigError, match="is not callable"):
        register_controller("broken", 3)
    with pytest.raises(InvalidConfigError, match="omega_Q and omega_R are weights of the LQI"):
        driver.with_weights(omega_Q=1.0)
