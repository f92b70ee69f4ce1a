"""The bench over REST beyond scans: `slrig doctor`'s checks (GET /v1/doctor) and each projector's
power control where the config gives it one (GET/PUT /v1/projectors/{name}/power, PUT .../input).

Power calls go through the job worker like every device call (rig.service.worker_calls): between
jobs, answered within a bounded time, refused while a job runs.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from fastapi import APIRouter, Path
from pydantic import BaseModel, Field

from drivers.base import PowerControl
from rig.api.models import _Request
from rig.api.security import MUTATING, READING
from rig.doctor import check
from rig.opened_rig import Rig
from rig.service import JobService, SetupRefusedError

ProjectorName = Annotated[str, Path(pattern=r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$", description="a projector's name")]


class DoctorProblem(BaseModel):
    device: str
    problem: str = Field(description="what is wrong and how to fix it")


class DoctorView(BaseModel):
    problems: list[DoctorProblem] = Field(description="empty: the machine has what the config needs")


class PowerRequest(_Request):
    on: bool = Field(description="light source on (true) or off")


class InputRequest(_Request):
    input: str = Field(min_length=1, max_length=32, description="the driver's input name (hdmi, vga; PJLink: 31)")


class BlankRequest(_Request):
    blank: bool = Field(description="mute the picture (true) or show the input again")


class PowerView(BaseModel):
    projector: str
    state: Literal["off", "on", "cooling", "warming"]


def bench_router(service: JobService, errors: dict[int | str, dict[str, Any]]) -> APIRouter:
    router = APIRouter(tags=["bench"], responses=errors)

    @router.get("/doctor", response_model=DoctorView, dependencies=READING)
    def doctor() -> dict[str, Any]:
        """What this machine lacks for the config (device nodes, groups, libraries, udev rules,
        a calibration): `slrig doctor` without opening any device."""
        return {"problems": check(service.config)}

    def power_call(name: str, action: Any, what: str) -> dict[str, Any]:
        def run(rig: Rig) -> dict[str, Any]:
            device = _power_device(service, rig, name)
            action(device)
            return {"projector": name, "state": device.power_state()}

        return service.calls.call(run, service.busy_with, f"{name}'s {what}")  # type: ignore[no-any-return]

    @router.get("/projectors/{name}/power", response_model=PowerView, dependencies=READING)
    def power_state(name: ProjectorName) -> dict[str, Any]:
        if service.open_rig is None:  # reading must not open the rig, which switches projectors on
            raise SetupRefusedError("the rig is not open (a job, aim mode or a power change opens it)")
        return power_call(name, lambda device: None, "power state")

    @router.put("/projectors/{name}/power", response_model=PowerView, dependencies=MUTATING)
    def set_power(name: ProjectorName, body: PowerRequest) -> dict[str, Any]:
        return power_call(name, lambda device: device.power(body.on), "power")

    @router.put("/projectors/{name}/input", response_model=PowerView, dependencies=MUTATING)
    def select_input(name: ProjectorName, body: InputRequest) -> dict[str, Any]:
        return power_call(name, lambda device: device.select_input(body.input), "input")

    @router.put("/projectors/{name}/blank", response_model=PowerView, dependencies=MUTATING)
    def blank(name: ProjectorName, body: BlankRequest) -> dict[str, Any]:
        return power_call(name, lambda device: device.blank(body.blank), "blanking")

    return router


def _power_device(service: JobService, rig: Rig, name: str) -> PowerControl:
    names = [p.name for p in service.config.projectors]
    if name not in names:
        raise SetupRefusedError(f"projector: this rig has {', '.join(names)}, not {name!r}")
    if service.config.projectors[names.index(name)].power is None:
        raise SetupRefusedError(f"{name} has no power control (config: projectors[{names.index(name)}].power)")
    held = next((d for d in rig.extras if d.name == f"{name}-power"), None)
    device = getattr(held, "control", held)  # the rig holds it through rig.assembly's ProjectorPower
    if not isinstance(device, PowerControl):
        raise SetupRefusedError(f"{name}'s power control is not open")
    return device
