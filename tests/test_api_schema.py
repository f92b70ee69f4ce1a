"""schemathesis against the OpenAPI schema: generated requests to every operation, in process, on
the simulated bench. No 5xx, and every response conforms to the schema (status, content type,
body) -- also for JSON bodies that JSON itself cannot carry back: a number replaced by NaN,
Infinity or 1e999, a string by one with a lone surrogate."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import schemathesis
from fastapi.testclient import TestClient
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from schemathesis import GenerationMode
from schemathesis.specs.openapi.checks import positive_data_acceptance

from rig.api.app import create_app
from rig.api.security import ApiSettings
from tests.test_api import KEY, _service

EXAMPLES_PER_OPERATION = 30
POISONED_PER_OPERATION = 15
# The same cases on every run (a suite that passes passes again); bench/reliability.py runs longer,
# randomised ones.
DETERMINISTIC = {"derandomize": True, "database": None}
UNREPRESENTABLE_NUMBERS = ["NaN", "Infinity", "-Infinity", "1e999"]
UNREPRESENTABLE_STRINGS = ['"\\ud800"', '"scan\\udfff"']


def _poisoned(value: object, draw: st.DrawFn) -> str:
    """`value` as JSON text with each number or string, by a draw, replaced by what JSON cannot
    echo (a client's bytes need not be valid JSON numbers or valid Unicode)."""
    if isinstance(value, dict):
        return "{" + ", ".join(f"{json.dumps(k)}: {_poisoned(v, draw)}" for k, v in value.items()) + "}"
    if isinstance(value, list):
        return "[" + ", ".join(_poisoned(v, draw) for v in value) + "]"
    if isinstance(value, (int, float)) and not isinstance(value, bool) and draw(st.booleans()):
        return draw(st.sampled_from(UNREPRESENTABLE_NUMBERS))
    if isinstance(value, str) and draw(st.booleans()):
        return draw(st.sampled_from(UNREPRESENTABLE_STRINGS))
    return json.dumps(value)


def test_every_operation_conforms_to_the_schema(tmp_path: Path) -> None:
    operations, failures = schema_failures(tmp_path, EXAMPLES_PER_OPERATION, POISONED_PER_OPERATION, DETERMINISTIC)
    assert operations >= 14
    assert not failures, "\n\n".join(failures)


def schema_failures(tmp_path: Path, examples: int, poisoned: int, randomness: dict[str, Any]) -> tuple[int, list[str]]:
    """Every operation's generated requests (and, with a JSON body, poisoned ones) against an app
    with no worker; the operations tried and each one's failure."""
    service = _service(tmp_path, start=False, max_queue=4)  # no worker: requests only, no scans running
    app = create_app(service, ApiSettings(api_key=KEY, allowed_hosts=("testserver", "localhost")))
    schema = schemathesis.openapi.from_asgi("/openapi.json", app)
    client = TestClient(app, base_url="http://localhost")
    common = {"deadline": None, "suppress_health_check": list(HealthCheck), **randomness}
    failures: list[str] = []
    operations = 0
    try:
        for result in schema.get_all_operations():
            operation = result.ok()
            operations += 1
            cases = operation.as_strategy(generation_mode=GenerationMode.POSITIVE) | operation.as_strategy(
                generation_mode=GenerationMode.NEGATIVE
            )

            check = _conforming(cases, common, examples, _excluded_checks(operation))
            try:
                check()
                if operation.body:  # a JSON body: again with values JSON cannot carry back
                    _poison_bodies(operation, client, settings(**common, max_examples=poisoned))
            except Exception as exc:  # collect every operation's failure, then report them all
                failures.append(f"{operation.method.upper()} {operation.path}: {exc}")
    finally:
        service.store.close()
    return operations, failures


def _excluded_checks(operation: schemathesis.APIOperation) -> list[Any]:
    """An upload's schema says bytes; whether they are an image (judged from its header) it cannot
    say, so a schema-valid upload may rightly be refused 422. Likewise a calibration's board and lens
    model: the schema gives their form, not whether a marker fits its square or a model exists."""
    upload = operation.method.upper() == "PUT" and operation.path.startswith("/v1/imports/")
    calibration = operation.method.upper() == "POST" and operation.path == "/v1/calibrations"
    return [positive_data_acceptance] if upload or calibration else []


def _conforming(cases: Any, common: dict[str, Any], examples: int, excluded: list[Any]) -> Any:
    @given(case=cases)
    @settings(**common, max_examples=examples)
    def check(case: schemathesis.Case) -> None:
        case.call_and_validate(headers={"X-API-Key": KEY}, excluded_checks=excluded)

    return check


def _poison_bodies(operation: schemathesis.APIOperation, client: TestClient, chosen: settings) -> None:
    @given(case=operation.as_strategy(generation_mode=GenerationMode.POSITIVE), data=st.data())
    @chosen
    def check(case: schemathesis.Case, data: st.DataObject) -> None:
        if not isinstance(case.body, (dict, list)):
            return
        body = _poisoned(case.body, data.draw)
        response = client.request(
            case.method,
            case.formatted_path,
            params=case.query,
            content=body.encode("utf-8", "surrogatepass"),
            headers={"X-API-Key": KEY, "Content-Type": "application/json"},
        )
        assert response.status_code < 500, f"{response.status_code} for {body!r}: {response.text}"
        case.validate_response(response, excluded_checks=[positive_data_acceptance])  # poisoned: 422 is right

    check()
