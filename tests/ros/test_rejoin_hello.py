"""A restarted host that later waits for envelopes says hello with the step it has reached
(bringup/engine/ros/host.py ``_hello``).

What went wrong (the kill-9 campaign, tests/faults/test_kill9_campaign.py, under load): the router was
killed, restarted from its checkpoint of step 19, rejoined and ran on; at step 28 an envelope was
late by more than ``rejoin_period_s``, the host repeated its hello - still with ``resume_k`` 19 - and
the clock, at step 28 with step 27 acked, took it for a host whose saved state was lost and stopped
the run. Oracle: the clock's own rule (clock_node.py ``_serve_rejoins``: a hello must resume at least
after the last acked step), applied to the hello the host sends.
"""

from __future__ import annotations

import pytest

from bringup.engine.ros.host import HostError, ParticipantHost

pytestmark = [pytest.mark.faults]


def _restarted_host(resume_k: int, done_k: int) -> tuple[ParticipantHost, list[dict]]:
    h = object.__new__(ParticipantHost)
    h.role, h.slots, h.inboxes_by_topic = "router", [], {}
    h.resume_k, h.done_k = resume_k, done_k
    h.ack_timeout_s, h.rejoin_period_s = 0.3, 0.05
    hellos: list[dict] = []
    h._ack = lambda **kw: hellos.append(kw)

    def spin_until(cond, timeout_s, what):
        if not cond():
            raise HostError(f"host {h.role}: {what} (waited {timeout_s:g} s)")
    h._spin_until = spin_until
    return h, hellos


def test_late_envelopes_after_a_rejoin_ask_with_the_step_reached():
    h, hellos = _restarted_host(resume_k=19, done_k=27)
    arrived = iter([False, False, True])
    h._wait_envelopes(lambda: next(arrived), "step 28 at t_ns=270000000000: envelopes missing")
    assert hellos and all(kw["hello"] and kw["resume_k"] == 27 for kw in hellos)
    cur_k = 28  # the clock's rule: a hello resumes at least after the last acked step (cur_k - 1)
    assert all(kw["resume_k"] >= cur_k - 1 for kw in hellos)


def test_first_hello_after_a_restart_names_the_checkpoint():
    h, hellos = _restarted_host(resume_k=19, done_k=19)
    h._hello()
    assert hellos[-1]["resume_k"] == 19


def test_a_fresh_host_says_it_has_no_checkpoint():
    h, hellos = _restarted_host(resume_k=-1, done_k=-1)
    h._hello()
    assert hellos[-1]["resume_k"] == -1


def test_envelopes_that_never_come_still_fail_the_step():
    h, hellos = _restarted_host(resume_k=19, done_k=27)
    with pytest.raises(HostError, match="envelopes missing"):
        h._wait_envelopes(lambda: False, "step 28 at t_ns=270000000000: envelopes missing")
    assert len(hellos) >= 2 and {kw["resume_k"] for kw in hellos} == {27}
