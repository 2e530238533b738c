"""Counted nouns in the command lines' messages (sim.support.text)."""
from sim.support.text import count


def test_count_says_one_episode_and_three_envs():
    assert count(1, "episode") == "1 episode"
    assert count(0, "episode") == "0 episodes"
    assert count(3, "env") == "3 envs"
    assert count(2, "negative direction") == "2 negative directions"
    assert count(2, "matrix", "matrices") == "2 matrices" and count(1, "matrix", "matrices") == "1 matrix"
