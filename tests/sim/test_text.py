"""Counted nouns and numbers in the command lines' messages (sim.support.text)."""
from sim.support.text import count, number


def test_count_says_one_episode_and_three_envs():
    assert count(1, "episode") == "1 episode"
    assert count(0, "episode") == "0 episodes"
    assert count(3, "env") == "3 envs"
    assert count(2, "negative direction") == "2 negative directions"
    assert count(2, "matrix", "matrices") == "2 matrices" and count(1, "matrix", "matrices") == "1 matrix"


def test_number_is_a_dash_until_there_is_a_value():
    assert number(1.23456) == "1.23" and number(-0.5, ".3f") == "-0.500" and number(12.7, ".0f") == "13"
    for missing in (float("nan"), float("inf"), None, "x"):
        assert number(missing) == "–"
