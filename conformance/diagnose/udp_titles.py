"""The titles of the UDP family's mechanisms and of the TCP check field (see :mod:`.udp_family`).

Like :mod:`.titles`: one line, what the box does, the clause, and after a dash the fix (or the flag
to rerun with, when the box reads a profile decision another way).
"""

from __future__ import annotations

from typing import Any

from ..i18n import gettext


def crc_name(name: str) -> str:
    """A crcmod name as the CRC catalogue writes it: crc-ccitt-false → CRC-16/CCITT-FALSE, crc-16 → CRC-16/ARC."""
    bare = name.removeprefix("crc-16-").removeprefix("crc-")
    return "CRC-16/ARC" if bare == "16" else f"CRC-16/{bare.upper()}"


def _cover(detail: dict[str, Any]) -> str:
    first, last = detail["cover"]
    return gettext("bytes {first}..{last}").format(first=first, last=last)


def coverage_part(detail: dict[str, Any]) -> str:
    """The part of a frame a CRC covers, in the protocol's words (``cover``: its first and last byte)."""
    first, last = detail["cover"]
    if (first, last) == (0, 11):
        return gettext("the 12-byte header only, not over the blocks")
    if (first, last) == (2, 11):
        return gettext("the header without its start word, not over the blocks")
    if first == 12:
        return gettext("the blocks only, not over the header")
    if first == 2:
        return gettext("the frame without its start word (bytes 2..{last})").format(last=last)
    return gettext("bytes {first}..{last} only, not over the whole frame before the check field").format(
        first=first, last=last)


def of(kind: str, d: dict[str, Any]) -> str:
    if kind == "udp-answer-port":
        return gettext("Sends its UDP answers to the request's source port {offset} ({to} for a request from "
                       "{source}): F7 asks for each datagram answered — answer to the source address and port of the "
                       "request").format(offset=f"{d['offset']:+d}", to=d["to"], source=d["source"])
    if kind == "udp-answer-source":
        return gettext("Sends its UDP answers from port {source}, not from the port the request went to ({port}): "
                       "a robot's connected socket drops them (F7) — answer from the socket that received the "
                       "request").format(source=d["source"], port=d["port"])
    if kind == "udp-crc-algorithm":
        what = gettext("Signs and checks") if d.get("signs") else gettext("Checks")
        return gettext("{what} UDP frames with {crc}, not {profile}: rerun with `--crc {name}` to test the "
                       "rest (F7)").format(what=what, crc=crc_name(d["crc"]), profile=crc_name(d["profile"]),
                                           name=d["crc"]) + (
            f" `--crc-byte-order {d['order']}`" if d.get("order_differs") else "")  # a flag: the same in every language
    if kind == "udp-crc-byte-order":
        return gettext("Writes the UDP CRC ({crc}) {order}-endian: rerun with `--crc-byte-order {order}` to test the "
                       "rest (F7)").format(crc=crc_name(d["crc"]), order=d["order"])
    if kind == "udp-silent":
        return gettext("Answers no UDP datagram ({tried} CRC algorithm and byte order combinations tried; nothing "
                       "came back to the sending port or its neighbours) while it answers over TCP: F7 asks for "
                       "each datagram answered — check that the UDP socket answers the request's source").format(
            tried=d["tried"])
    if kind == "udp-crc-unchecked":
        return gettext("UDP CRC not checked: answers 0000 to a NONE datagram whose check field ({check}) no CRC-16 "
                       "computes: R7 asks for such datagrams dropped — compute the CRC of bytes 0..12+N×L−1 and drop "
                       "the datagram when it differs from the check field").format(check=d["check"])
    if kind == "udp-crc-one-byte":
        return gettext("Checks only one byte of the UDP CRC: a NONE datagram whose CRC has byte {ignored} of 2 (frame "
                       "byte {at}) changed is answered 0000, one with byte {checked} changed is dropped: R7 asks for a "
                       "datagram with a wrong CRC dropped — compare both bytes of the CRC").format(
            ignored=d["ignored"], checked=d["checked"], at=d["at"])
    if kind == "udp-crc-coverage":
        return gettext("Computes the UDP CRC over {part}: a pose datagram is answered only when its CRC covers {bytes} "
                       "(F7: the CRC covers bytes 0..12+N×L−1, the header and the blocks) — compute the CRC over the "
                       "header and every block").format(part=coverage_part(d), bytes=_cover(d))
    if kind == "udp-several-frames" and int(d["n"]) == 1:
        return gettext("Answers 0000 to the first frame of a datagram holding two and ignores the rest: it checks only "
                       "that a datagram is at least one frame long (F7/R7 ask for exactly one frame per datagram) — "
                       "drop a datagram whose length is not 12+N×L+2")
    if kind == "udp-several-frames":
        return gettext("Takes {n} frames from one datagram (answers 0000 to a pose and a register pose sent in one "
                       "datagram): F7/R7 ask for exactly one frame per datagram — drop a datagram whose length is "
                       "not 12+N×L+2").format(n=d["n"])
    if kind == "udp-trailing":
        return gettext("Answers 0000 to a UDP datagram with {n} bytes after its frame: F7/R7 ask for exactly one "
                       "frame per datagram — drop a datagram whose length is not 12+N×L+2").format(n=d["n"])
    if kind == "udp-short-completed":
        return gettext("Answers 0000 to a UDP datagram {missing} bytes short of its frame ({size} of {frame} bytes) "
                       "right after the same frame came whole, and drops it after another datagram: it completes a "
                       "short datagram with the bytes the previous datagram left in its receive buffer (R7 asks for "
                       "it dropped) — check that each datagram's length is exactly 12+N×L+2").format(
            missing=d["missing"], size=d["size"], frame=d["frame"])
    if kind == "udp-answer-frames":
        return gettext("Writes UDP answers that are not one frame ({size} bytes for a {frame}-byte frame): F7 asks "
                       "for one frame per datagram — send each answer in its own datagram").format(
            size=d["size"], frame=d["frame"])
    if kind == "udp-answer-crc":
        seen = " or ".join(crc_name(n) + f" ({o})" for n, o in d.get("matches", [])[:2]) or gettext("no CRC-16")
        return gettext("Signs its UDP answers with a check field ({check}) that is not the {crc} of the frame (it "
                       "matches {seen}): F7 asks for the profile's CRC both ways — sign answers as requests are "
                       "checked").format(check=d["check"], crc=crc_name(d["profile"]), seen=seen)
    if kind == "tcp-check-field":
        seen = " or ".join(crc_name(n) + f" ({o})" for n, o in d.get("matches", [])[:2])
        what = gettext(" (the {crc} of the frame: a UDP habit)").format(crc=seen) if seen else ""
        return gettext("Writes {check} in the check field of its TCP answers{what}: F6 asks for 00 00 over TCP — "
                       "write 00 00").format(check=d["check"], what=what)
    if kind == "tcp-crc-refused" and d.get("own"):
        return gettext("Checks the TCP check field with {own}, as over UDP: refuses a request carrying its {crc} "
                       "({check}), accepts 00 00 and its own CRC; F6 asks a TCP receiver to ignore the check field "
                       "(SHOULD) — accept any check field over TCP").format(own=crc_name(d["own"]),
                                                                            crc=crc_name(d["crc"]), check=d["check"])
    if kind == "tcp-crc-refused":
        return gettext("Refuses a TCP request whose check field holds its CRC ({check}) and accepts it with 00 00: "
                       "F6 asks a TCP receiver to ignore the check field (SHOULD) — accept any check field over "
                       "TCP").format(check=d["check"])
    return str(d.get("title", kind))
