"""The graph studies' settings (pliant.learn.graph.settings): the options they vary make the
agents' configuration and the run folders' labels."""

from __future__ import annotations

import argparse

from pliant.learn.graph.settings import CONFIGS, add_evaluator_options, agent_config, label_of


def _args(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    parser.add_argument("--scene", default="CartStemContact")
    add_evaluator_options(parser)
    return parser.parse_args(list(argv))


def test_the_defaults_are_the_scenes_configuration():
    config = agent_config(_args())
    assert config == {**CONFIGS["CartStemContact"], "evaluator_target": "max"}
    assert label_of("graph", config) == "graph" and label_of("sac", config) == "sac"


def test_options_change_the_configuration_and_the_label():
    config = agent_config(
        _args("--internal", "shared", "--evaluator-entropy", "0.3", "--updates-per-episode", "5")
    )
    assert config["internal"] == "shared" and config["updates_per_episode"] == 5
    assert label_of("graph", config) == "graph_shared_entropy0.3_episode5"
    assert label_of("sac", config) == "sac_episode5"
    scoped = agent_config(_args("--update-scope", "all", "--avoid-cycles"))
    assert label_of("convex", scoped) == "convex_avoid_all"
