"""Pure maths of inertial test (no hardware): sub-packages ``identification``, ``noise``, ``periodic``, ``drift``,
and the shared frames and units beside them (``units``, ``gimbal``, ``earth``)."""
