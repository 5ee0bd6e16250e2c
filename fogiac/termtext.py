"""What a node wrote, made safe for the operator's terminal: plain text and line breaks only.

Why: ``fogiac logs`` prints what a program on a host wrote, and a terminal obeys escape sequences in
it. OSC 52 sets the operator's clipboard, other OSC strings retitle windows or write hyperlinks, CSI
moves the cursor and clears lines (hiding what was printed above), DCS and friends reach the
terminal's own parsers. Every escape sequence, C1 control (8-bit CSI and OSC included) and control
character other than newline and tab is dropped; the rest is printed as it came.

The filter keeps its state between chunks, so ``--follow`` can feed it whatever ``read`` returned: a
sequence split across two reads is still dropped whole, and an unterminated string (an OSC without its
end) swallows what follows it rather than reaching the terminal, as the terminal itself would have.
"""

from __future__ import annotations

import codecs

_ESC, _BEL = "\x1b", "\x07"
_KEEP = frozenset("\n\t")
# After ESC: these open a string that runs to BEL or ST (ESC \): OSC, DCS, SOS, PM, APC.
_STRINGS = frozenset("]PX^_")
# The same, and CSI, as 8-bit C1 controls (U+009D OSC, U+0090 DCS, ..., U+009B CSI).
_C1_STRINGS = frozenset("\x9d\x90\x98\x9e\x9f")
_C1_CSI, _C1_ST = "\x9b", "\x9c"


class TerminalFilter:
    """Feed text (or bytes, decoded as UTF-8) in pieces; get back only what is safe to print."""

    def __init__(self) -> None:
        self._state = "text"  # text | esc | csi | string | string-esc | intermediate
        self._decoder = codecs.getincrementaldecoder("utf-8")(errors="replace")

    def feed_bytes(self, data: bytes, *, final: bool = False) -> str:
        return self.feed(self._decoder.decode(data, final))

    def feed(self, text: str) -> str:
        out: list[str] = []
        state = self._state
        for ch in text:
            code = ord(ch)
            if state == "text":
                if ch == _ESC:
                    state = "esc"
                elif ch == _C1_CSI:
                    state = "csi"
                elif ch in _C1_STRINGS:
                    state = "string"
                elif ch in _KEEP or (code >= 0x20 and code != 0x7F and not 0x80 <= code <= 0x9F):
                    out.append(ch)
            elif state == "esc":
                if ch == "[":
                    state = "csi"
                elif ch in _STRINGS:
                    state = "string"
                elif 0x20 <= code <= 0x2F:  # intermediate bytes: ESC ( B and the like take one more
                    state = "intermediate"
                else:  # a two-character sequence (ESC c resets the terminal): dropped with its letter
                    state = "text" if ch != _ESC else "esc"
            elif state == "intermediate":
                if not 0x20 <= code <= 0x2F:
                    state = "text"
            elif state == "csi":
                if 0x40 <= code <= 0x7E:  # the final byte ends it
                    state = "text"
                elif ch == _ESC:
                    state = "esc"
            elif state == "string":
                if ch in (_BEL, _C1_ST):
                    state = "text"
                elif ch == _ESC:
                    state = "string-esc"
            elif state == "string-esc":
                state = "text" if ch == "\\" else ("string-esc" if ch == _ESC else "string")
        self._state = state
        return "".join(out)


def clean(text: str) -> str:
    """``text`` with every escape sequence and control character but newline and tab removed."""
    return TerminalFilter().feed(text)
