import os

import pytest
from simtest import REPO

from goniosim import scenario as S


def test_unknown_keys_are_named():
    with pytest.raises(S.ScenarioError, match="session.sped"):
        S.from_dict({"session": {"sped": 3}})
    with pytest.raises(S.ScenarioError, match=r"faults\[0\].kind"):
        S.from_dict({"faults": [{"kind": "gremlins", "at_capture": 1}]})
    with pytest.raises(S.ScenarioError, match=r"faults\[0\].rate"):
        S.from_dict({"faults": [{"kind": "lamp-step", "at_capture": 1, "rate": 2}]})
    with pytest.raises(S.ScenarioError, match="at_capture or at_hours"):
        S.from_dict({"faults": [{"kind": "reboot"}]})
    with pytest.raises(S.ScenarioError, match="material.preset"):
        S.from_dict({"material": {"preset": "velvet"}})
    with pytest.raises(S.ScenarioError, match="session.format"):
        S.from_dict({"session": {"format": "png"}})
    with pytest.raises(S.ScenarioError, match="rig: unknown"):
        S.from_dict({"rig": {"min_sep": 3}})


def test_demo_scenario_takes_rig_and_plan_from_the_daemon_config():
    sc = S.load(os.path.join(REPO, "sim", "scenarios", "demo.toml"))
    assert sc.plan.captures == 6561 and sc.rig.min_separation_deg == 12.0
    assert sc.capture_count == 6561
    for name in sorted(os.listdir(os.path.join(REPO, "sim", "scenarios"))):
        S.load(os.path.join(REPO, "sim", "scenarios", name))
