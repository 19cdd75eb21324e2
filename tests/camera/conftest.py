from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def rig():
    """The reference virtual camera (640x480, 2.5 m up, distorting lens) and its calibration
    from its own board and floor frames, as a user makes it."""
    from pac_host.camera.virtual import reference_rig

    return reference_rig()
