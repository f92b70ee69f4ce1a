"""PJLink class 1 commands as data: each body, the parameters a set takes, whether it can be
queried, and the shape of a query's answer. The loopback fake (drivers.fakes.pjlink) answers ERR1
and ERR2 from this table, and tests/test_protocol_tables.py encodes every line the driver sends
from it.

Source: PJLink Specifications, Class 1 (JBMIA), the command list; the values as summarised in
../shared/reference/hardware.md section 3.1 (from pypjlink2 1.2.2 and projector manuals' PJLink
tables). Syntax: `%1` + body + space + parameter + CR; a reply is `%1` + body + `=` + result + CR;
errors ERR1 (undefined command), ERR2 (parameter out of range), ERR3 (unavailable time), ERR4
(projector failure); a failed authentication is the line `PJLINK ERRA`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

SOURCE = "PJLink Specifications Class 1 (JBMIA), command list"


@dataclass(frozen=True)
class PjlinkCommand:
    body: str
    sets: str | None  # a regular expression of the parameters a set takes; None: query only
    answer: str  # a regular expression of a query's answer
    source: str

    def refuses(self, parameter: str) -> str | None:
        """ERR2 where the parameter is out of range for this command, else None."""
        if parameter == "?":
            return None
        if self.sets is None or not re.fullmatch(self.sets, parameter):
            return "ERR2"
        return None


COMMANDS = {
    c.body: c
    for c in (
        PjlinkCommand("POWR", "[01]", "[0-3]", f"{SOURCE}: POWR (query: 2 cooling, 3 warm-up)"),
        PjlinkCommand("INPT", "[1-5][1-9A-Z]", "[1-5][1-9A-Z]", f"{SOURCE}: INPT (type 1-5, then number)"),
        PjlinkCommand("AVMT", "[123][01]", "[123][01]", f"{SOURCE}: AVMT (10/11 video, 20/21 audio, 30/31 both)"),
        PjlinkCommand("ERST", None, "[0-2]{6}", f"{SOURCE}: ERST (fan, lamp, temperature, cover, filter, other)"),
        PjlinkCommand("LAMP", None, r"\d+ [01]( \d+ [01])*", f"{SOURCE}: LAMP (hours and on-flag per lamp)"),
        PjlinkCommand("INST", None, r"[1-5][1-9A-Z]( [1-5][1-9A-Z])*", f"{SOURCE}: INST (the inputs)"),
        PjlinkCommand("NAME", None, ".{0,64}", f"{SOURCE}: NAME"),
        PjlinkCommand("INF1", None, ".{0,32}", f"{SOURCE}: INF1 (manufacturer)"),
        PjlinkCommand("INF2", None, ".{0,32}", f"{SOURCE}: INF2 (product)"),
        PjlinkCommand("INFO", None, ".{0,32}", f"{SOURCE}: INFO (other information)"),
        PjlinkCommand("CLSS", None, "[12]", f"{SOURCE}: CLSS (class)"),
    )
}


def encode(body: str, parameter: str) -> bytes:
    """The command line as the table says it is written (no authentication prefix)."""
    return f"%1{body} {parameter}\r".encode("ascii")
