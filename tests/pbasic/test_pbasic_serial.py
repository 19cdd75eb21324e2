"""Serial I/O in Stamp time: SEROUT framing, SERIN timeouts, WAIT, STR, DEC, lost bytes, echo."""

from __future__ import annotations

import pytest

from pac_sim.pbasic import SERIN, StampEnded, StampNotListening

LISTEN = (
    "buf VAR Byte(4)\nn VAR Word\nc VAR Byte\n"
    "Main:\n"
    "  SEROUT 16, 16468, [\"R\"]\n"
    "  SERIN 16, 16468, 50, NoData, [WAIT(\"GO\"), STR buf\\3, DEC n, c]\n"
    "  SEROUT 16, 16468, [\"OK\", DEC n, \",\", STR buf\\3, c]\n"
    "  END\n"
    "NoData:\n"
    "  SEROUT 16, 16468, [\"T\"]\n"
    "  GOTO Main\n"
)


def test_serout_frames_take_ten_bit_times(run):
    s = run("SEROUT 1, 84, [\"AB\", DEC 42, HEX4 $1F, \" \", SDEC -5, BIN 5, IHEX2 10]\nEND\n")
    assert s.output.data(1) == b"AB42001F -5101$0A"
    ends = [t for t, pin, _ in s.output.frames if pin == 1]
    assert ends[1] - ends[0] == 1040  # 9600 baud: 10 bits of 104 us


def test_serin_times_out_in_stamp_time(stamp):
    s = stamp(LISTEN)
    w = s.run_until_serin(1.0)
    assert w.pin == 16 and w.deadline_us - w.since_us == 50_000
    t0 = s.now_us
    s.advance(60_000)  # nothing arrives: the 50 ms timeout fires, the program goes on
    w2 = s.run_until_serin(1.0)
    assert s.output.take(16) == b"RTR"
    assert w2.since_us - t0 >= 50_000


def test_serin_wait_str_dec_and_reply(stamp):
    s = stamp(LISTEN)
    s.run_until_serin()
    s.output.take()
    s.feed(b"xxGGOabc123;Z")  # noise before the marker, a partial match, then the frame
    assert s.run(1_000_000) == "ended"
    echo_and_reply = s.output.take(16)
    assert echo_and_reply.startswith(b"xxGGOabc123;Z")  # the programming port echoes
    assert echo_and_reply.endswith(b"OK123,abcZ")
    assert s.var("n") == 123 and s.var("c") == ord("Z")


def test_bytes_sent_while_not_listening_are_lost(stamp):
    s = stamp("a VAR Byte\nb VAR Byte\nPAUSE 10\nSERIN 1, 84, 100, Late, [a]\nEND\n"
              "Late:\n  b = 1\n  END\n")
    s.feed(b"Q", pin=1, at_us=0)  # arrives during the PAUSE: no SERIN, no buffer
    assert s.run_for(1) == "ended"
    assert s.var("b") == 1 and s.var("a") == 0
    assert s.line(1).lost == 1


def test_byte_sent_after_serin_starts_is_received(stamp):
    s = stamp("a VAR Byte\nPAUSE 10\nSERIN 1, 84, [a]\nEND\n")
    assert s.run() == SERIN
    s.feed(b"Q", pin=1, at_us=s.now_us + 3000)
    assert s.run() == "ended"
    assert s.var("a") == ord("Q")
    assert s.now_us >= 10_000 + 3000 + 1040


def test_timeout_restarts_with_each_byte(stamp):
    s = stamp("buf VAR Byte(3)\nt VAR Bit\nSERIN 1, 84, 20, Late, [STR buf\\3]\nEND\n"
              "Late:\n  t = 1\n  END\n")
    s.run()
    s.feed(b"a", pin=1, at_us=s.now_us + 15_000)
    s.feed(b"b", pin=1, at_us=s.now_us + 30_000)  # 15 ms after "a": still inside its timeout
    s.feed(b"c", pin=1, at_us=s.now_us + 45_000)
    assert s.run_for(1) == "ended"
    assert s.var("t") == 0 and bytes(s.var(f"B{i}") for i in range(3)) == b"abc"


def test_not_listening_is_reported(stamp):
    s = stamp("DO\n  PULSOUT 12, 750\n  PAUSE 20\nLOOP\n")
    with pytest.raises(StampNotListening, match="the Stamp is not listening: no SERIN within 2 s"):
        s.run_until_serin(2.0)
    assert 1.99 <= s.now_s <= 2.1


def test_ended_program_is_reported(stamp):
    with pytest.raises(StampEnded, match=r"t\.bs2:3: the program reached END"):
        stamp("END\n").run_until_serin(1.0)


def test_debug_is_captured_not_printed(run, capsys):
    s = run("x VAR Byte\nx = 7\nDEBUG \"x=\", DEC x, CR, DEC ? x\nEND\n")
    assert s.debug_text == "x=7\rx = 7\r"
    assert capsys.readouterr().out == ""


def test_serin_number_formats_skip_and_waitstr(stamp):
    s = stamp("key VAR Byte(3)\na VAR Word\nb VAR Word\nc VAR Word\nd VAR Word\ne VAR Word\n"
              "key(0) = \"K\"\nkey(1) = \"Y\"\n"
              "SERIN 2, 84, [WAITSTR key\\2, SKIP 2, HEX a, BIN b, SDEC c, DEC2 d, IHEX e]\nEND\n")
    s.run()
    s.feed(b"xKKYzz1f;101 x-42!12345 q$FF.", pin=2)
    assert s.run() == "ended"
    assert [s.var(v) for v in "abcde"] == [0x1F, 5, 0x10000 - 42, 12, 0xFF]


def test_serin_without_timeout_waits_for_ever_in_silence(stamp):
    s = stamp("x VAR Byte\nSERIN 1, 84, [x]\nEND\n")
    assert s.run_for(3.0) == SERIN
    assert s.now_us >= 3_000_000
    s.feed(b"!", pin=1)
    assert s.run() == "ended" and s.var("x") == ord("!")
