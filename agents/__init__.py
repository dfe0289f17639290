"""Baseline agents (installed as ``rbenvs_agents``): training, evaluation, analytic baselines."""
