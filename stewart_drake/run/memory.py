"""The memory a run holds, estimated from its scenario before anything is allocated, and the
refusal of runs the machine cannot hold (a study's workers: several runs at once)."""

from __future__ import annotations

from .scenario import Scenario

#: Memory a run holds, bytes, measured as the peak RSS of ``stewart-drake reproduce`` on
#: synthetic phantom traces of 1 and 25 minutes at 1 kHz (the robot as built, logs every
#: millisecond): 0.40 GB before anything is logged (Python, Drake, the plant, the compiled
#: controller, the reference's check) and 0.44 kB per logged sample all told (1.06 GB for 25
#: minutes; 1.76 kB and 3.2 GB before the logs were sized for the run). Of a sample: the
#: float32 logs (0.16 kB: pose and rate, torques, the controller's status, integral and error),
#: the plant state every ``state_log_period_s`` (61 float64 every 10 ms: 0.05 kB a
#: millisecond), the feed-forward table and sample times (0.07 kB a control period: the
#: reference itself is evaluated a stretch at a time, and the tables are dropped once the run
#: is read), the result's reference and feed-forward (0.1 kB) and the report's intermediates
#: (0.08 kB). Upper bounds with some slack:
RUN_BASE_BYTES = 0.4e9
LOG_BYTES_PER_SAMPLE = 0.5e3
CONTROL_BYTES_PER_SAMPLE = 0.15e3
STATE_BYTES_PER_SAMPLE = 1.0e3
#: A learner's status log: up to 16 float64 per plant-state sample (it is logged with the
#: plant state, every ``state_log_period_s``), with slack.
LEARNER_BYTES_PER_SAMPLE = 0.2e3


def run_memory_bytes(scenario: Scenario) -> float:
    """Estimated peak memory of one run of ``scenario``, bytes (inf-safe for huge durations):
    :data:`RUN_BASE_BYTES`, its control-period samples, its logged samples and its plant-state
    samples (see :data:`LOG_BYTES_PER_SAMPLE`), a learner's status log
    (:data:`LEARNER_BYTES_PER_SAMPLE`), plus what the reference itself holds (a CSV
    reference's spline, :meth:`~stewart_drake.references.motion.ReferenceConfig.memory_bytes`)."""
    d = float(scenario.duration_s)
    return (
        RUN_BASE_BYTES
        + scenario.reference.memory_bytes()
        + (d / scenario.control_period_s + 1) * CONTROL_BYTES_PER_SAMPLE
        + (d / scenario.log_period_s + 1) * LOG_BYTES_PER_SAMPLE
        + (d / scenario.state_log_period_s + 1) * STATE_BYTES_PER_SAMPLE
        + (scenario.learning is not None)
        * (d / scenario.state_log_period_s + 1)
        * LEARNER_BYTES_PER_SAMPLE
    )


def check_run_memory(scenario: Scenario, runs_at_once: int = 1, change: str | None = None):
    """Refuse, before anything is allocated, runs that need more memory than the machine has.

    Args:
        scenario: the run.  runs_at_once: how many such runs are in memory together (workers).
        change: what the message tells to change (default: duration_s or log_period_s).
    Raises:
        InvalidConfigError: one line with the estimate and the memory available.
    """
    from ..base.checks import check_memory

    on_reference, coarser = scenario.reference.memory_note()
    what = (
        f"{'a run of' if runs_at_once == 1 else f'{runs_at_once} runs at once, each of'} "
        f"{scenario.duration_s:g} s logged every {scenario.log_period_s:g} s{on_reference}"
    )
    need = runs_at_once * run_memory_bytes(scenario)
    check_memory(
        what, need, change or ("shorten duration_s (--duration) or lengthen log_period_s" + coarser)
    )
