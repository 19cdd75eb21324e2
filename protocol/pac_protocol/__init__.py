"""The ServoBot wire protocol (protocol/PROTOCOL.md): frames, messages, decoder, host link."""

from pac_protocol.decoder import FrameDecoder
from pac_protocol.frame import Frame, check_value, parse_frame
from pac_protocol.messages import PROTOCOL_VERSION, Cmd, Err, Message, decode_message

__all__ = [
    "PROTOCOL_VERSION",
    "Cmd",
    "Err",
    "Frame",
    "FrameDecoder",
    "Message",
    "check_value",
    "decode_message",
    "parse_frame",
]
