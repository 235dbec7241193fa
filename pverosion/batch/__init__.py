"""Batch runs: scenario files expanded into jobs, run on Dask distributed, resumable.

>>> from pverosion.batch import parse_scenario
>>> scenario = parse_scenario('''
... [input]
... example = "rock"
... subdivisions = 2
... [[stages]]
... stage = "weather"
... iterations = 5
... [sweep]
... "weather.power" = [1.0, 2.0]
... "input.seed" = [1, 2, 3]
... ''')
>>> len(scenario.jobs), scenario.jobs[4].label
(6, 'weather.power=2.0, input.seed=2')
"""

from pverosion.batch.job import job_figures, run_job
from pverosion.batch.manifest import Manifest
from pverosion.batch.runner import BatchReport, run_batch
from pverosion.batch.scenario import STAGES, Job, Scenario, ScenarioError, load_scenario, parse_scenario

__all__ = [
    "STAGES",
    "BatchReport",
    "Job",
    "Manifest",
    "Scenario",
    "ScenarioError",
    "job_figures",
    "load_scenario",
    "parse_scenario",
    "run_batch",
    "run_job",
]
