"""The codec as functions of a profile: encode and parse with the cached :class:`~.codec.Codec`.

``parse_frame`` checks a complete frame in the order codec.py's docstring gives and raises a
typed :class:`~.errors.ProtocolError` naming the first clause it breaks.
"""

from __future__ import annotations

from .codec import codec_for
from .constants import TransferType, Transport
from .frames import Block, Frame, Header
from .profile import DEFAULT_PROFILE, Profile


def encode(frame: Frame, profile: Profile = DEFAULT_PROFILE, transport: Transport = Transport.TCP) -> bytes:
    """The bytes of ``frame``: TCP with check 00 00 (F6), UDP with the CRC (F7)."""
    return codec_for(profile).encode(frame, transport)


def encode_tcp(frame: Frame, profile: Profile = DEFAULT_PROFILE) -> bytes:
    return codec_for(profile).encode(frame, Transport.TCP)


def encode_udp(frame: Frame, profile: Profile = DEFAULT_PROFILE) -> bytes:
    return codec_for(profile).encode(frame, Transport.UDP)


def encode_body(frame: Frame, profile: Profile = DEFAULT_PROFILE) -> bytes:
    """Header and blocks of a frame, without the check field."""
    return codec_for(profile).encode_body(frame)


def encode_header(header: Header, profile: Profile = DEFAULT_PROFILE) -> bytes:
    """Pack twelve header bytes, legal or not (fields must fit their widths)."""
    return codec_for(profile).encode_header(header)


def encode_block(block: Block, profile: Profile = DEFAULT_PROFILE) -> bytes:
    return codec_for(profile).encode_block(block)


def encode_raw(
    header: Header,
    body: bytes = b"",
    check: bytes | None = None,
    profile: Profile = DEFAULT_PROFILE,
    transport: Transport = Transport.TCP,
) -> bytes:
    """Craft any frame: header fields and body as given; ``check=None`` computes it."""
    return codec_for(profile).encode_raw(header, body, check, transport)


def parse_header(data: bytes, profile: Profile = DEFAULT_PROFILE) -> Header:
    """The header of ``data`` (at least 12 bytes) as raw integers."""
    return codec_for(profile).parse_header(data)


def parse_frame(
    data: bytes,
    profile: Profile = DEFAULT_PROFILE,
    transport: Transport = Transport.TCP,
    expect: TransferType | None = None,
) -> Frame:
    """Parse exactly one complete frame; raise a ProtocolError naming the clause.

    ``expect`` is the transfer type the receiver expects (F3); None accepts both.
    """
    return codec_for(profile).parse(data, transport, expect)


def decode_datagram(
    data: bytes, profile: Profile = DEFAULT_PROFILE, expect: TransferType | None = None
) -> Frame:
    """F7/R7: one UDP datagram must be exactly one frame with a correct CRC."""
    return codec_for(profile).parse(data, Transport.UDP, expect)
