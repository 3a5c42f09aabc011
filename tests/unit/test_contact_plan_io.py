"""Contact plan files: the study's CSV, ION, HDTN JSON, both ways."""

import io

import pytest

from orbit_clock.contact_plan import (CONTACT_PLAN_FORMATS, Contact, ContactPlan, ContactPlanError, parse_contact_plan,
                                      read_contact_plan, write_contact_plan)

PLAN = ContactPlan([Contact(0.0, 21600.0, "sat_11", "sat_12", 1000.0, 2e-05),
                    Contact(381.5, 2340.498, "sat_11", "sat_21", 8000.0, 1.0)])


def test_study_plan(paper_inputs):
    p = read_contact_plan(paper_inputs / "contact_plan_3p_8s.csv", rate_bps=1000)
    assert len(p) == 1384 and len(p.nodes) == 24 and all(c.rate_bps == 1000 for c in p)
    assert p.contacts[0] == Contact(0.0, 21600.0, "sat_11", "sat_12", 1000.0, 2e-05)


@pytest.mark.parametrize("fmt", CONTACT_PLAN_FORMATS)
def test_round_trip(fmt, paper_inputs):
    for plan in (PLAN, read_contact_plan(paper_inputs / "contact_plan_3p_8s.csv", rate_bps=1000)):
        s = io.StringIO()
        write_contact_plan(plan, fmt, s)
        assert parse_contact_plan(s.getvalue(), fmt).contacts == plan.contacts


def test_ion_text_exact():
    s = io.StringIO()
    write_contact_plan(PLAN, "ion", s)
    lines = [x for x in s.getvalue().splitlines() if not x.startswith("#")]
    assert lines[0] == "a contact +0 +21600 11 12 125"  # ION rates are bytes/s
    assert lines[1] == "a contact +381.5 +2340.498 11 21 1000"
    assert lines[2] == "a range +0 +21600 11 12 2e-05"


def test_hand_written_ion_and_hdtn():
    ion = "# plan\na contact +10 +20 11 12 125\na range +0 +100 12 11 1\nm production 1000000\n"
    p = parse_contact_plan(ion, "ion")
    assert p.contacts == [Contact(10.0, 20.0, "sat_11", "sat_12", 1000.0, 1.0)]  # ranges are symmetric
    js = '{"contacts": [{"contact": 0, "source": 11, "dest": 12, "startTime": 1, "endTime": 5, ' \
         '"rateBitsPerSec": 1000, "owlt": 0}]}'
    assert parse_contact_plan(js, "hdtn-json").contacts == [Contact(1.0, 5.0, "sat_11", "sat_12", 1000.0, 0.0)]


def test_errors_name_the_file(tmp_path, paper_inputs):
    with pytest.raises(ContactPlanError, match="rate"):
        read_contact_plan(paper_inputs / "contact_plan_3p_8s.csv")
    bad = tmp_path / "bad.csv"
    bad.write_text("start_s,end_s,origin,destination,range_light_s\n1,x,s11,s12,0\n")
    with pytest.raises(ContactPlanError, match=r"bad.csv:2"):
        read_contact_plan(bad, rate_bps=1)
    with pytest.raises(ContactPlanError, match="suffix"):
        read_contact_plan(tmp_path / "plan.xyz")
