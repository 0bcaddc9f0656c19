"""Built-in robots: nominal kinematics (standard DH, degrees and mm as published) and joint limits.

Each entry is plain data; :func:`robocal.robot` turns it into a :class:`robocal.Robot`.

Sources
-------
``hsr-jr680``
    HSR JR680, the paper's Table I (Li, Li, Luo, IEEE TIM 2023). Joint limits are not published
    in the paper; the ones below are wide approximations that contain every configuration of
    the public HSR-RobotCali data (whose q3 readings lie at 209-221 deg).
``abb-irb120``
    ABB IRB 120 product manual (a2 = 270, a3 = 70, d1 = 290, d4 = 302, d6 = 72 mm) in the usual
    standard-DH form with theta offsets -90 deg (joint 2) and 180 deg (joint 6); limits from the
    product specification.
``ur10``
    Universal Robots UR10 (CB3) nominal DH from the manufacturer (d1 = 127.3, a2 = -612,
    a3 = -572.3, d4 = 163.941, d5 = 115.7, d6 = 92.2 mm); every joint +-360 deg.

Joints whose axis is nominally parallel to the previous joint's axis (the link's ``alpha`` is 0)
are flagged ``hayati``: calibration estimates Hayati's ``beta`` there instead of ``d``.
"""

from __future__ import annotations

# Rows: (alpha_deg, a_mm, d_mm, theta_deg, (lower_deg, upper_deg), hayati)
BUILTIN: dict[str, dict] = {
    "hsr-jr680": {
        "description": "HSR JR680 6R industrial robot (payload 80 kg), nominal DH of the paper's Table I",
        "dh": [
            (-90.0, 250.0, 653.5, 0.0, (-170.0, 170.0), False),
            (0.0, 900.0, 0.0, -90.0, (-150.0, 90.0), True),
            (90.0, -205.0, 0.0, 180.0, (-90.0, 270.0), False),
            (-90.0, 0.0, 1030.2, 0.0, (-360.0, 360.0), False),
            (90.0, 0.0, 0.0, 90.0, (-135.0, 135.0), False),
            (0.0, 0.0, 200.6, 0.0, (-360.0, 360.0), False),
        ],
    },
    "abb-irb120": {
        "description": "ABB IRB 120 6R robot, nominal DH from the product manual",
        "dh": [
            (-90.0, 0.0, 290.0, 0.0, (-165.0, 165.0), False),
            (0.0, 270.0, 0.0, -90.0, (-110.0, 110.0), True),
            (-90.0, 70.0, 0.0, 0.0, (-110.0, 70.0), False),
            (90.0, 0.0, 302.0, 0.0, (-160.0, 160.0), False),
            (-90.0, 0.0, 0.0, 0.0, (-120.0, 120.0), False),
            (0.0, 0.0, 72.0, 180.0, (-400.0, 400.0), False),
        ],
    },
    "ur10": {
        "description": "Universal Robots UR10 (CB3), nominal DH from the manufacturer",
        "dh": [
            (90.0, 0.0, 127.3, 0.0, (-360.0, 360.0), False),
            (0.0, -612.0, 0.0, 0.0, (-360.0, 360.0), True),
            (0.0, -572.3, 0.0, 0.0, (-360.0, 360.0), True),
            (90.0, 0.0, 163.941, 0.0, (-360.0, 360.0), False),
            (-90.0, 0.0, 115.7, 0.0, (-360.0, 360.0), False),
            (0.0, 0.0, 92.2, 0.0, (-360.0, 360.0), False),
        ],
    },
}
