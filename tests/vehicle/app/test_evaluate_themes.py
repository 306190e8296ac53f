"""The expert drives every theme and randomisation (it steers from the map, never the image),
through the evaluation every pilot goes through."""

from __future__ import annotations

import pytest

from parts.sim.themes import theme_list, theme_of
from vehicle.app.evaluate import evaluate


@pytest.mark.parametrize("lanes, width, themes", [(1, 0.8, "road,indoor,park"), (2, 1.2, "road,indoor")])
@pytest.mark.parametrize("randomize", [None, 5, "latency2"])
def test_expert_drives_every_theme_and_randomisation_without_leaving_the_road(cfg, lanes, width, themes,
                                                                              randomize):
    ranges = {"latency": (2, 2)} if randomize == "latency2" else {}
    seed = 9 if randomize == "latency2" else randomize
    c = cfg.replace(SIM_THEME=themes, SIM_RANDOMIZE=seed, SIM_RANDOMIZE_RANGES=ranges, SIM_LANES=lanes,
                    SIM_ROAD_WIDTH=width, SIM_OFF_TRACK_CTE=width / 2)
    seeds = list(range(300, 309))
    report = evaluate("expert", seeds, laps=1, cfg=c)
    assert [t["theme"] for t in report["tracks"]] == [theme_of(theme_list(themes), i) for i in range(len(seeds))]
    if randomize == "latency2":
        assert {t["conditions"]["latency"] for t in report["tracks"]} == {2}
    assert report["overall"]["interventions"] == 0 and report["overall"]["autonomy"] == 100.0
    assert report["overall"]["laps_completed"] == len(seeds)


@pytest.mark.slow
@pytest.mark.parametrize("randomize", [1, 2, 3, 4, 6, 7])
def test_expert_drives_many_randomisation_draws(cfg, randomize):
    """Six more draws (the demo's training draw 1 and held-out draws among them) over 12 tracks of
    every theme, so 72 randomised episodes in all."""
    c = cfg.replace(SIM_THEME="road,indoor,park", SIM_RANDOMIZE=randomize)
    seeds = list(range(400, 412))
    report = evaluate("expert", seeds, laps=1, cfg=c)
    assert {t["conditions"]["randomize"] for t in report["tracks"]} == {randomize}
    assert report["overall"]["interventions"] == 0 and report["overall"]["autonomy"] == 100.0
    assert report["overall"]["laps_completed"] == len(seeds)
