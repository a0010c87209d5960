"""Each test run and bench claims a ROS domain of its own: a held domain is skipped, all held is refused."""
import pytest

from rollability_ros.core.graph import claim_domain


def test_a_held_domain_is_skipped_and_none_free_is_refused_in_one_line():
    first, first_lock = claim_domain(230, 232, start=230)
    second, second_lock = claim_domain(230, 232, start=230)
    third, third_lock = claim_domain(230, 232, start=231)
    try:
        assert first == 230 and second == 231 and third == 232
        with pytest.raises(RuntimeError, match=r"^no free ROS_DOMAIN_ID in 230\.\.232"):
            claim_domain(230, 232)
    finally:
        for handle in (first_lock, second_lock, third_lock):
            handle.close()
    again, lock = claim_domain(230, 232, start=230)   # closed handles release their domains
    lock.close()
    assert again == 230
