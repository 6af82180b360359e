"""Scenario files shipped with stewart-drake (installed as the package ``stewart_drake.scenarios``;
``stewart_drake.run.scenario_io.load_scenario(name)`` reads them)."""
