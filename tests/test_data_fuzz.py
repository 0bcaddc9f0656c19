"""Random and malformed bytes reach the user as a robocal exception, never a crash."""

from __future__ import annotations

import zipfile
from io import BytesIO

from hypothesis import given
from hypothesis import strategies as st

from robocal.data import load, read_canonical
from robocal.exceptions import RobocalError

HEADERS = [
    b"q1,q2,L\n",
    b"x,y,z,q1,q2,q3,q4,q5,q6,L\n",
    b"q1,q2,q3,q4,q5,q6,L\n",
    b"q1,x,y,z,qw,qx,qy,qz,t,temp\n",
    b"Timestamp;shoulder_pan_joint;shoulder_lift_joint;elbow_joint;wrist_1_joint;wrist_2_joint;wrist_3_joint;"
    b"measurement_x;measurement_y;measurement_z;measurement_rx;measurement_ry;measurement_rz\n",
]
CELLS = st.sampled_from([b"1", b"-2.5", b"1,5", b"nan", b"inf", b"", b"x", b"1e400", b"\xff", b"\x00", b'"', b";", b",", b"\n", b"\r", b"2,02011E+13"])
BODY = st.lists(CELLS, max_size=60).map(b"".join)


def _zip(payload: bytes) -> bytes:
    buffer = BytesIO()
    with zipfile.ZipFile(buffer, "w") as z:
        z.writestr("[Content_Types].xml", payload)
    return buffer.getvalue()


def check(tmp_path_factory, data: bytes):
    path = tmp_path_factory.mktemp("fuzz") / "f.csv"
    path.write_bytes(data)
    for read in (read_canonical, load):
        try:
            d = read(path)
        except RobocalError:
            continue
        assert len(d) >= 1 and d.q.shape[0] == d.y.shape[0]


@given(st.binary(max_size=300))
def test_random_bytes(tmp_path_factory, data):
    check(tmp_path_factory, data)


@given(st.sampled_from(HEADERS), BODY)
def test_malformed_tables(tmp_path_factory, header, body):
    check(tmp_path_factory, header + body)


@given(st.binary(max_size=200))
def test_corrupt_workbooks(tmp_path_factory, payload):
    check(tmp_path_factory, _zip(payload))
    check(tmp_path_factory, b"PK\x03\x04" + payload)
