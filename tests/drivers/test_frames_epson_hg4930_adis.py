"""Frame descriptions of the Epson M-G370 UART burst, the Honeywell HG4930 inertial message and an ADIS16475
32-bit burst through a USB-ISS SPI bridge.

No public driver's tests or documentation print a captured frame of these units, so each test frame below is
BUILT BYTE BY BYTE from the public format documentation named at the frame (field order, widths, byte order,
checksum rule), with raw values chosen here; the checksum bytes are written out and re-derived by an
independent loop from the documented rule, and the expected engineering values are computed with the
conversion formulas of the public drivers, never with this project's decoder. Every one-bit flip is rejected
(the two bytes the ADIS bridge clocks in during the burst command carry no data and are covered by no
checksum: a flip there is shown to change nothing decoded). The round trips go through the simulated unit's
encoder with damage, decoded in random chunks."""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest

from analysis.units import CELSIUS_ZERO
from drivers.imu_unit.decoder import FrameDecoder
from drivers.imu_unit.description import FLAG_BITS, compile_format, load_frame
from drivers.imu_unit.samples import SampleConverter, encode_samples
from tests.drivers.frame_support import decode_in_random_chunks

G0 = 9.80665  # the Epson driver's and the ADIS data sheet's g (m/s^2 per g)

# ---- Epson M-G370PDF1 UART burst --------------------------------------------------------------------------
# Layout: Epson M-G3xx data sheets, table "UART Data Packet Format (UART Burst/Auto Mode)" (address 0x80, ND/EA
# flags, TEMP, X/Y/Z GYRO, X/Y/Z ACCL, COUNT, CHECKSUM, CR 0x0D; big-endian), here with TEMP/GYRO/ACCL at 32 bits;
# checksum and conversions as Epson's public driver cubicleguy/ess_imu_ros2_uart_driver does them
# (src/sensor_epsonUart.c: 16-bit sum of the big-endian words after the address up to COUNT; temperature
# (T - 172621824) * SF / 65536 + 25; gyro SF / 65536 deg/s; accel SF / 65536 mg; SFs of src/sensor_epsonG370PDF1.h).
EPSON_G370 = bytes.fromhex(
    "80"  # address of the burst
    "fe00"  # ND flags: temperature, gyro X/Y/Z, accel X/Y/Z new; EA (bit 0) clear
    "0a000000"  # TEMP (32-bit) = 167772160
    "00100000"
    "ffe00000"
    "0fffe000"  # X/Y/Z GYRO = 1048576, -2097152, 268427264
    "00a00000"
    "fffb0000"
    "02800000"  # X/Y/Z ACCL = 10485760, -327680, 41943040
    "1234"  # COUNT
    "0d3e"  # CHECKSUM
    "0d"  # delimiter CR
)
EPSON_SF = {"gyro": 0.0151515, "accel": 0.400, "temp": -0.0037918}

# ---- Honeywell HG4930 inertial message 0x02 ---------------------------------------------------------------
# Layout: HG4930 Performance and Installation Manual ("Standard and SDLC inertial message (0x02)", published with
# bolderflight/hg4930 as docs/HG4930_Performance_and_Installation_Manual.pdf): 0x0E, 0x02, control data (rate
# 600 * 2^-20 rad/s, acceleration 600 * 0.3048 * 2^-14 m/s^2, status words 1 and 2), delta angle X/Y/Z (2^-33
# rad), delta velocity X/Y/Z (2^-27 * 0.3048 m/s), checksum = 16-bit sum of the 21 preceding words; LS byte and
# LS word first.
HG4930_INERTIAL = bytes.fromhex(
    "0e02"  # IMU address, message ID
    "6400"
    "38ff"
    "2c01"  # angular rate X/Y/Z = 100, -200, 300
    "e803"
    "18fc"
    "b705"  # linear acceleration X/Y/Z = 1000, -1000, 1463
    "0100"  # status word 1: 2-bit counter 1, everything OK
    "0000"  # status word 2A: software version 0, every test OK
    "00000001"
    "0000c0ff"
    "15cd5b07"  # delta angle X/Y/Z = 16777216, -4194304, 123456789
    "00000008"
    "aacbedff"
    "00000004"  # delta velocity X/Y/Z = 134217728, -1193046, 67108864
    "55b5"  # checksum
)
# the control message 0x01 the unit sends five times between two inertial messages (same manual, "(0x01)")
HG4930_CONTROL = bytes.fromhex("0e01640038ff2c01e80318fcb705020000008f07")

# ---- ADIS16475-2 32-bit burst through a Devantech USB-ISS ---------------------------------------------------
# Bridge: USB-ISS technical documentation (robot-electronics.co.uk, SPI_IO command 0x61: the answer is 0xFF (ACK)
# then the bytes clocked in), as tork-a/adi_driver (src/adis16470.cpp, update_burst) uses it. Burst: ADIS16475
# data sheet, burst read with MSC_CTRL BURST_SIZE = 1 (DIAG_STAT, then X/Y/Z_GYRO and X/Y/Z_ACCL as LOW, OUT
# register pairs, TEMP_OUT, DATA_CNTR, checksum = 16-bit sum of the 30 preceding bytes, as analogdevicesinc/no-OS
# drivers/imu/adis.c checks it); scales of the data sheet: gyro 0.025 deg/s per OUT LSB (-2 grade), accel
# 1.25 mg per OUT LSB, each / 65536 for OUT:LOW; TEMP_OUT 0.1 degC per LSB.
ADIS16475_BRIDGE = bytes.fromhex(
    "ff"  # USB-ISS ACK
    "0000"  # clocked in while 0x6800 (burst command) went out
    "0000"  # DIAG_STAT: no error
    "3456"
    "0012"  # X_GYRO_LOW, X_GYRO_OUT  -> 0x00123456
    "0000"
    "ffe0"  # Y_GYRO -> 0xFFE00000
    "8000"
    "0100"  # Z_GYRO -> 0x01008000
    "0000"
    "0320"  # X_ACCL -> 0x03200000 (800 OUT LSB = 1 g)
    "1234"
    "fff0"  # Y_ACCL -> 0xFFF01234
    "ffff"
    "0000"  # Z_ACCL -> 0x0000FFFF
    "00fa"  # TEMP_OUT = 250
    "0102"  # DATA_CNTR = 258
    "084f"  # checksum
)

PUBLIC_BUILT = [
    ("epson-g370-burst", EPSON_G370),
    ("honeywell-hg4930", HG4930_INERTIAL),
    ("adis16475-usb-iss", ADIS16475_BRIDGE),
]


def _decode(name: str, data: bytes, rate: float):
    fmt = compile_format(load_frame(name), None, rate)
    batch, stats = FrameDecoder(fmt.desc).feed(data)
    return batch, stats, (SampleConverter(fmt).convert(batch) if len(batch) else None)


def test_the_built_frames_carry_the_documented_checksums():
    """The checksum bytes written above, re-derived from each documented rule by an independent loop."""
    e = EPSON_G370
    assert sum(struct.unpack(">16H", e[1:33])) % 65536 == struct.unpack(">H", e[33:35])[0] and e[-1] == 0x0D
    for m, n in ((HG4930_INERTIAL, 21), (HG4930_CONTROL, 9)):
        assert sum(struct.unpack(f"<{n}H", m[: 2 * n])) % 65536 == struct.unpack("<H", m[2 * n :])[0]
    a = ADIS16475_BRIDGE
    assert sum(a[3:33]) % 65536 == struct.unpack(">H", a[33:35])[0]


def test_epson_g370_burst_decodes_to_the_drivers_conversions():
    _b, stats, s = _decode("epson-g370-burst", EPSON_G370, 250.0)
    assert (stats.frames, stats.rejected, stats.garbage_bytes) == (1, 0, 0)
    temp, gx, gy, gz, ax, ay, az = struct.unpack(">i3i3i", EPSON_G370[3:31])
    deg = math.pi / 180
    np.testing.assert_allclose(s.gyro[0], np.array([gx, gy, gz]) * EPSON_SF["gyro"] / 65536 * deg, rtol=1e-12)
    np.testing.assert_allclose(s.accel[0], np.array([ax, ay, az]) * EPSON_SF["accel"] / 65536 * G0 / 1000, rtol=1e-12)
    t_c = (temp - 172621824) * EPSON_SF["temp"] / 65536 + 25
    assert s.temperature[0] == pytest.approx(t_c + CELSIUS_ZERO, abs=1e-9)
    assert s.status[0] == 0


def test_epson_flags_and_a_missing_delimiter():
    frame = bytearray(EPSON_G370)
    frame[1:3] = struct.pack(">H", 0xFE01)  # EA: an error in the unit
    frame[33:35] = struct.pack(">H", sum(struct.unpack(">16H", bytes(frame[1:33]))) % 65536)
    _b, stats, s = _decode("epson-g370-burst", bytes(frame), 250.0)
    assert stats.frames == 1 and s.status[0] == sum(
        1 << FLAG_BITS[c] for c in ("accel_x", "accel_y", "accel_z", "gyro_x", "gyro_y", "gyro_z")
    )
    no_cr = EPSON_G370[:-1] + b"\x0a"
    _b, stats, _s = _decode("epson-g370-burst", no_cr, 250.0)
    assert (stats.frames, stats.rejected) == (0, 1)


def test_hg4930_inertial_message_decodes_to_the_manuals_weights():
    rate = 100.0  # the standard model's inertial message rate
    _b, stats, s = _decode("honeywell-hg4930", HG4930_INERTIAL, rate)
    assert (stats.frames, stats.rejected, stats.garbage_bytes) == (1, 0, 0)
    da = np.array(struct.unpack("<3i", HG4930_INERTIAL[18:30]), dtype=float)
    dv = np.array(struct.unpack("<3i", HG4930_INERTIAL[30:42]), dtype=float)
    np.testing.assert_allclose(s.gyro[0], da * 2.0**-33 * rate, rtol=1e-12)
    np.testing.assert_allclose(s.accel[0], dv * 2.0**-27 * 0.3048 * rate, rtol=1e-12)
    assert s.status[0] == 0


def test_hg4930_control_messages_are_checked_and_skipped():
    rate = 100.0
    stream = (HG4930_CONTROL * 5 + HG4930_INERTIAL) * 3
    batch, stats, s = _decode("honeywell-hg4930", stream, rate)
    assert (stats.frames, stats.other_frames, stats.rejected, stats.garbage_bytes) == (3, 15, 0, 0)
    assert stats.bit_frames == 0 and not batch.bit
    bad = bytearray(HG4930_CONTROL)
    bad[5] ^= 0x04
    _b, stats, _s = _decode("honeywell-hg4930", bytes(bad) + HG4930_INERTIAL, rate)
    assert (stats.frames, stats.other_frames, stats.rejected) == (1, 0, 1)


def test_hg4930_status_words_flag_their_channels():
    frame = bytearray(HG4930_INERTIAL)
    frame[14:16] = struct.pack("<H", 1 << 9)  # gyro Y failed
    frame[16:18] = struct.pack("<H", 1 << 14)  # accelerometer health failed
    frame[42:44] = struct.pack("<H", sum(struct.unpack("<21H", bytes(frame[:42]))) % 65536)
    _b, stats, s = _decode("honeywell-hg4930", bytes(frame), 100.0)
    want = (1 << FLAG_BITS["gyro_y"]) | sum(1 << FLAG_BITS[c] for c in ("accel_x", "accel_y", "accel_z"))
    assert stats.frames == 1 and s.status[0] == want


def test_adis16475_burst_through_the_bridge_decodes_to_the_data_sheet_scales():
    _b, stats, s = _decode("adis16475-usb-iss", ADIS16475_BRIDGE, 2000.0)
    assert (stats.frames, stats.rejected, stats.garbage_bytes) == (1, 0, 0)
    words = struct.unpack(">15H", ADIS16475_BRIDGE[3:33])

    def pair(i: int) -> int:  # LOW at words[i], OUT at words[i + 1]
        v = (words[i + 1] << 16) | words[i]
        return v - (1 << 32) if v & 0x80000000 else v

    gyro = np.array([pair(1), pair(3), pair(5)], dtype=float) * 0.025 / 65536 * math.pi / 180
    accel = np.array([pair(7), pair(9), pair(11)], dtype=float) * 1.25e-3 / 65536 * G0
    np.testing.assert_allclose(s.gyro[0], gyro, rtol=1e-12)
    np.testing.assert_allclose(s.accel[0], accel, rtol=1e-12)
    assert s.accel[0][0] == pytest.approx(G0, rel=1e-12)  # 800 OUT LSB of 1.25 mg = 1 g
    assert s.temperature[0] == pytest.approx(25.0 + CELSIUS_ZERO)
    assert s.status[0] == 0


@pytest.mark.parametrize("name,frame", PUBLIC_BUILT, ids=[n for n, _ in PUBLIC_BUILT])
def test_every_single_bit_flip_is_rejected(name, frame):
    desc = load_frame(name)
    rate = 100.0
    _b, _st, clean = _decode(name, frame, rate)
    free = {1, 2} if name == "adis16475-usb-iss" else set()  # bytes clocked in during the command: no data
    for bit in range(8 * len(frame)):
        bad = bytearray(frame)
        bad[bit // 8] ^= 1 << (bit % 8)
        batch, stats = FrameDecoder(desc).feed(bytes(bad))
        if bit // 8 in free:
            s = SampleConverter(compile_format(desc, None, rate)).convert(batch)
            assert len(batch) == 1 and np.array_equal(s.gyro, clean.gyro) and np.array_equal(s.accel, clean.accel)
            continue
        assert len(batch) == 0, f"bit {bit} flipped was accepted"
        assert stats.rejected == (0 if bit < 8 * len(desc.sync) else 1), f"bit {bit}"


def _samples(n: int, rng: np.random.Generator):
    accel = rng.normal(0, 5, (n, 3))
    gyro = rng.normal(0, 1, (n, 3))
    return accel, gyro, np.full(n, 298.15) + rng.normal(0, 2, n)


@pytest.mark.parametrize("name", ["epson-g370-burst", "honeywell-hg4930", "adis16475-usb-iss"])
def test_round_trip_through_the_simulated_units_encoder_with_damage(name):
    """The simulated unit's output stage in each format, garbage between frames and two corrupted frames, fed in
    random chunks: exactly the corrupted frames are lost, the rest decode to the samples sent within half a
    count of the field (the quantisation of the format)."""
    rate = 250.0
    fmt = compile_format(load_frame(name), None, rate)
    rng = np.random.default_rng(11)
    n = 400
    idx = np.arange(n)
    accel, gyro, temp = _samples(n, rng)
    rows = encode_samples(fmt, idx, idx / rate, accel, gyro, temp)
    first = fmt.desc.sync[0]
    allowed = np.array([b for b in range(256) if b != first], dtype=np.uint8)
    pieces, flipped = [], {60, 250}
    for i in range(n):
        if i % 41 == 7:
            pieces.append(rng.choice(allowed, 9).tobytes())
        r = rows[i].copy()
        if i in flipped:
            r[20] ^= 0x10
        pieces.append(r.tobytes())
    dec, s, _ = decode_in_random_chunks(fmt, b"".join(pieces), rng, 3 * fmt.length)
    kept = np.array([i for i in range(n) if i not in flipped])
    assert dec.total.frames == kept.size and dec.total.rejected == len(flipped)
    conv = fmt.conversions
    g_lsb = max(abs(conv[f.name].factor) for f in fmt.desc.fields if f.channel == "gyro_x")
    a_lsb = max(abs(conv[f.name].factor) for f in fmt.desc.fields if f.channel == "accel_x")
    per = rate if name == "honeywell-hg4930" else 1.0  # increments: one count per sample interval
    np.testing.assert_allclose(s.gyro, gyro[kept], rtol=0, atol=0.5001 * g_lsb * per)
    np.testing.assert_allclose(s.accel, accel[kept], rtol=0, atol=0.5001 * a_lsb * per)
    if fmt.desc.counter is not None:
        assert s.gaps == len(flipped)


@pytest.mark.parametrize("name", ["epson-g370-burst", "honeywell-hg4930", "adis16475-usb-iss"])
def test_tablebench_decode_reads_a_capture_and_auto_detects_the_format(tmp_path, capsys, name):
    """``tablebench decode --frame auto`` on a capture in each format (the HG4930's with its control messages
    between the inertial ones): the format is recognised, every frame decoded, the .npy written."""
    from benches.cli.main import main

    rate = 100.0 if name == "honeywell-hg4930" else 1000.0
    fmt = compile_format(load_frame(name), None, rate)
    n = 500
    idx = np.arange(n)
    accel, gyro, temp = _samples(n, np.random.default_rng(3))
    rows = encode_samples(fmt, idx, idx / rate, accel, gyro, temp)
    between = HG4930_CONTROL * 5 if name == "honeywell-hg4930" else b""
    cap = tmp_path / f"{name}.bin"
    cap.write_bytes(b"".join(between + r.tobytes() for r in rows))
    out = tmp_path / "decoded.npy"
    assert main(["decode", "--frame", "auto", "--rate", f"{rate:g}", str(cap), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert f"detected {name}" in text and f"frames {n}, rejected (bad checksum) 0, garbage bytes 0" in text
    if between:
        assert f"other messages {5 * n}" in text
    assert np.load(out).shape[0] == n
