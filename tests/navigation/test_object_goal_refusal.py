"""An object goal the apartment has no instance of is refused before the episode, in the one line that
``ambulo navigate --object`` prints too (``object_episode.goal_instances``)."""

import pytest

from ambulo.navigation.object_episode import run_object_episode


def test_a_class_the_apartment_lacks_is_refused_naming_the_classes_it_has():
    # apartment 5 has no table (tests/navigation/test_cli_navigate.py asks the CLI the same)
    with pytest.raises(ValueError, match=r"^apartment 5 has no table; it has armchair, bed, cabinet, desk, shelf, sofa$"):
        run_object_episode(5, 0, "table", known_object=True)
