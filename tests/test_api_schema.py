"""schemathesis against the OpenAPI schema: generated requests to every operation, in process, on
the simulated bench. No 5xx, and every response conforms to the schema (status, content type,
body)."""

from __future__ import annotations

from pathlib import Path

import schemathesis
from hypothesis import HealthCheck, given, settings
from schemathesis import GenerationMode

from rig.api.app import create_app
from rig.api.security import ApiSettings
from tests.test_api import KEY, _service

EXAMPLES_PER_OPERATION = 30


def test_every_operation_conforms_to_the_schema(tmp_path: Path) -> None:
    service = _service(tmp_path, start=False, max_queue=4)  # no worker: requests only, no scans running
    app = create_app(service, ApiSettings(api_key=KEY, allowed_hosts=("testserver", "localhost")))
    schema = schemathesis.openapi.from_asgi("/openapi.json", app)
    failures: list[str] = []
    operations = 0
    try:
        for result in schema.get_all_operations():
            operation = result.ok()
            operations += 1
            cases = operation.as_strategy(generation_mode=GenerationMode.POSITIVE) | operation.as_strategy(
                generation_mode=GenerationMode.NEGATIVE
            )

            @given(case=cases)
            @settings(max_examples=EXAMPLES_PER_OPERATION, deadline=None, suppress_health_check=list(HealthCheck))
            def check(case: schemathesis.Case) -> None:
                case.call_and_validate(headers={"X-API-Key": KEY})

            try:
                check()
            except Exception as exc:  # collect every operation's failure, then report them all
                failures.append(f"{operation.method.upper()} {operation.path}: {exc}")
    finally:
        service.store.close()
    assert operations >= 14
    assert not failures, "\n\n".join(failures)
