"""The checks of Drake's config structs a scenario holds (``plant``, ``simulator``): numbers
here (Drake aborts the process on some), names by Drake's own parser."""

import functools

from pydrake.multibody.plant import MultibodyPlantConfig
from pydrake.systems.analysis import SimulatorConfig

from ..base.checks import as_number
from ..base.errors import InvalidConfigError

#: Slowest real-time pacing accepted (besides 0, as fast as possible): the Simulator sleeps
#: between steps in C++, where no signal is handled, so a plant step must not wait more than a
#: fraction of a second (1 ms at 0.01: 0.1 s).
MIN_REALTIME_RATE = 0.01


def validate_plant_config(plant: MultibodyPlantConfig) -> None:
    """The fields of Drake's ``MultibodyPlantConfig`` besides the step and the approximation:
    numbers here (Drake aborts the process on some), names by Drake's own parser."""
    as_number("plant.penetration_allowance", plant.penetration_allowance, 0.0, lo_open=True)
    as_number("plant.stiction_tolerance", plant.stiction_tolerance, 0.0, lo_open=True)
    as_number("plant.sap_near_rigid_threshold", plant.sap_near_rigid_threshold, 0.0)
    for name in ("use_sampled_output_ports", "adjacent_bodies_collision_filters"):
        if not isinstance(getattr(plant, name, False), bool):
            raise InvalidConfigError(
                f"plant.{name} must be true or false, got {getattr(plant, name)!r}"
            )
    names = []
    for name in ("contact_model", "contact_surface_representation"):
        value = getattr(plant, name)
        if not isinstance(value, str):
            raise InvalidConfigError(f"plant.{name} must be a name, got {value!r}")
        names.append(value)
    problem = _drake_plant_names_problem(*names)
    if problem:
        raise InvalidConfigError(
            f"plant: {problem} (see Drake's MultibodyPlantConfig for the names)"
        )


@functools.lru_cache(maxsize=32)
def _drake_plant_names_problem(contact_model: str, contact_surface_representation: str) -> str:
    """Drake's own refusal of these names ("Unknown contact_model: 'bogus'"), "" if none: the
    names a Drake version knows are its own to say."""
    from pydrake.multibody.plant import AddMultibodyPlant
    from pydrake.systems.framework import DiagramBuilder

    config = MultibodyPlantConfig(
        time_step=1e-3,
        discrete_contact_approximation="sap",
        contact_model=contact_model,
        contact_surface_representation=contact_surface_representation,
    )
    try:
        AddMultibodyPlant(config, DiagramBuilder())
    except RuntimeError as err:
        return " ".join(str(err).split())
    return ""


def validate_simulator_config(config: SimulatorConfig) -> None:
    """The fields of Drake's ``SimulatorConfig``: the scheme among Drake's, a start at 0 s, and a
    real-time rate of 0 or at least :data:`MIN_REALTIME_RATE` (a slower one hangs the run)."""
    from pydrake.systems.analysis import GetIntegrationSchemes

    schemes = GetIntegrationSchemes()
    if config.integration_scheme not in schemes:
        raise InvalidConfigError(
            f"simulator.integration_scheme must be one of "
            f"{', '.join(schemes)}, got {config.integration_scheme!r}"
        )
    as_number("simulator.max_step_size", config.max_step_size, 0.0, lo_open=True)
    as_number("simulator.accuracy", config.accuracy, 0.0, 1.0, lo_open=True)
    if as_number("simulator.start_time", config.start_time) != 0.0:
        raise InvalidConfigError(
            f"simulator.start_time must be 0 (the reference and duration_s "
            f"count from t = 0), got {config.start_time!r}"
        )
    rate = as_number("simulator.target_realtime_rate", config.target_realtime_rate, 0.0)
    if 0.0 < rate < MIN_REALTIME_RATE:
        raise InvalidConfigError(
            f"simulator.target_realtime_rate must be 0 (as fast as "
            f"possible) or at least {MIN_REALTIME_RATE:g} (100 times slower "
            f"than real time), got {config.target_realtime_rate!r}"
        )
    for name in ("use_error_control", "publish_every_time_step"):
        if not isinstance(getattr(config, name, False), bool):
            raise InvalidConfigError(
                f"simulator.{name} must be true or false, got {getattr(config, name)!r}"
            )
