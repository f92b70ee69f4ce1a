"""The one way every protocol fake (and the simulated camera) injects a fault: a FaultPlan says
which fault and after how many exchanges (commands, frames; the serial and PJLink fakes fail from
the first command and refuse a count). Its text form, `silence@3`, travels
where objects cannot: in a pyserial URL (`simprojector://benq?fault=silence@0`) and in the
environment of a worker process (`SLRIG_FAKE_OAK=disconnect@1`)."""

from __future__ import annotations

import enum
from dataclasses import dataclass


class Fault(enum.StrEnum):
    SILENCE = "silence"  # the device stops answering: no reply, no frame, until the caller's timeout
    DISCONNECT = "disconnect"  # the device is gone: the transport fails (unplugged, link lost)


@dataclass(frozen=True)
class FaultPlan:
    fault: Fault
    after: int = 0  # exchanges that still succeed first

    def __str__(self) -> str:
        return f"{self.fault}@{self.after}"

    @classmethod
    def parse(cls, text: str) -> FaultPlan:
        """`silence`, `silence@3`, `disconnect@1`; ValueError naming the known faults otherwise."""
        name, _, after = text.partition("@")
        try:
            return cls(Fault(name), int(after) if after else 0)
        except ValueError:
            known = ", ".join(f.value for f in Fault)
            raise ValueError(f"fault {text!r}: expected <fault>[@<count>] with fault one of {known}") from None
