"""The manual's reliability table rows for bench/_attacks.py's figures (fault, tries, failed,
what held), written from the figures alone."""

from __future__ import annotations

from typing import Any


def attack_rows(result: dict[str, Any]) -> list[list[object]]:
    p, sch, t, s = result["poison"], result["schema"], result["strict_types"], result["slow_readers"]
    u, b, k = result["uploads"], result["bombs"], result["key_files"]
    rows: list[list[object]] = [
        [
            "poisoned bodies: NaN, Infinity, 1e999, lone surrogates in fields and free-form objects",
            p["requests"],
            p["5xx"] + p["accepted"] + p["listings_broken"],
            f"{p['5xx']} answered 5xx, {p['accepted']} accepted, {p['stored']} stored; "
            f"{p['listings_broken']} listings, pages or filters failed afterwards",
        ],
        [
            f"schema-generated requests, randomised ({sch['examples_per_operation']} per operation)",
            sch["operations"],
            len(sch["failures"]),
            "every response conforms to the schema, no 5xx"
            if not sch["failures"]
            else "; ".join(f[:80] for f in sch["failures"]),
        ],
        [
            'each typed body field with a value of another type (true for a number, "1" for an integer, ...)',
            t["requests"],
            t["accepted"] + t["5xx"],
            f"{t['accepted']} accepted, {t['5xx']} answered 5xx",
        ],
        [
            f"{s['connections']} unauthenticated connections asking for a 256 MB file, never reading",
            s["connections"],
            s["health_checks"] - s["health_answered"],
            f"{s['downloads_served']} served (per-address cap), {s['refused_429']} refused 429; health answered "
            f"{s['health_answered']} of {s['health_checks']} checks (slowest {s['health_ms_max']} ms); "
            f"{s['held_downloads_cut']} held downloads cut for their rate",
        ],
        _uploads_row(u),
        [
            f"a 20000x20000 16-bit PNG bomb ({b['bomb_bytes'] / 1e6:.2f} MB): uploaded, and as all "
            f"{b['frames']} frames of a reconstruction",
            2,
            int(b["upload_status"] < 300) + int(b["peak_rss_after_mb"] - b["peak_rss_before_mb"] > 200),
            f"upload {b['upload_status']}; reconstruction {b['reconstruction_status']}, "
            f"{b['reconstruction']}; daemon's peak memory {b['peak_rss_before_mb']} -> {b['peak_rss_after_mb']} MB",
        ],
        [
            "broken API key files: " + ", ".join(k["cases"]).replace("_", " "),
            len(k["cases"]),
            len(k["cases"]) - k["refused_with_2"] + k["key_in_log"],
            f"{k['refused_with_2']} refused at start with exit 2, the slowest in {k['slowest_s']} s; the key sent "
            f"in 6 places of a URL written to the log {k['key_in_log']} times",
        ],
    ]
    rows += _stop_rows(result["stop"])
    return rows


def _uploads_row(u: dict[str, Any]) -> list[object]:
    disk = (
        f"disk filled by uploads: {u['stored']} stored, then {u['full_disk_status']}, {u['free_mb']} MB left free "
        f"(reserve {'intact' if u['reserve_intact'] else 'broken'}), health {u['health']}"
        if "full_disk_status" in u
        else str(u["full_disk"])
    )
    wrong = int(u["empty_body"] < 300) + int(u["folder_limit"] != 413) + int(not u.get("reserve_intact", True))
    return [
        "uploads past the limits",
        3,
        wrong,
        f"empty body {u['empty_body']}; folder past its limit {u['folder_limit']}; {disk}",
    ]


def _stop_rows(stop: dict[str, Any]) -> list[list[object]]:
    slow = [state for state, s in stop.items() if s["max_s"] > 1.0 or not s["dark"]]
    return [
        [
            f"SIGTERM in each of {len(stop)} states (the simulated bench; `bench/stop_time.py`)",
            sum(s["runs"] for s in stop.values()),
            len(slow),
            "gone within (s, the most of its runs) "
            + ", ".join(f"{state.replace('_', ' ')} {s['max_s']}" for state, s in stop.items())
            + f"; projector dark in {sum(s['dark'] for s in stop.values())} of {len(stop)} states"
            + (f"; over 1 s or lit: {', '.join(slow)}" if slow else ""),
        ]
    ]
