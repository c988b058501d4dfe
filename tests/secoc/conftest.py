"""The SecOC tests' daemons and tools keep their freshness state in the test's own folder, never
in the user's ~/.local/state (the default of every process that holds keys)."""
import pytest


@pytest.fixture(autouse=True)
def _private_state_home(tmp_path_factory, monkeypatch):
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path_factory.mktemp("state")))
