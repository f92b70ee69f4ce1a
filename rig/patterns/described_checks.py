"""What a decode of another system's frames says about their description: the warnings, with
their numbers, that a description that ran but may not be what was projected deserves (a wrong
period or step count decodes, but to few pixels or beyond the projector), and the coarseness of
a phase read without unwrapping."""

from __future__ import annotations

from rig.patterns.correspondence import Correspondence
from rig.patterns.spec import PatternSpec

LEAST_DECODED = 0.5  # of the lit pixels: fewer decoded says the description is doubtful
MOST_BEYOND = 0.05  # of the lit pixels decoded beyond the projector's edge
EDGE_GAP_PX = 4  # a spanning period this little longer than the projector tells its ends apart poorly


def decoded_warnings(spec: PatternSpec, found: Correspondence) -> list[str]:
    """Warnings for a decode of `spec`'s frames, each with the numbers that raised it."""
    counts = found.counts
    lit, decoded = counts.get("lit", 0), counts.get("decoded", 0)
    out = []
    if spec.phase is not None and spec.phase.unwrap == "none":
        for axis in spec.axes:
            period = spec.phase.of(axis)[0].period_px
            noise = counts.get(f"phase_noise_millipx_{axis}", -1)
            measured = f"median {noise / 1000:.2f} px here" if noise >= 0 else "3 steps leave no residual to tell"
            out.append(
                f"phase.unwrap none: one {period:g} px period across the {spec.pixels(axis)} {axis}, read without "
                f"unwrapping: its coordinates are as coarse as its phase noise times {period:g} / 2 pi ({measured})"
            )
    if spec.phase is not None and spec.phase.unwrap in ("hierarchical", "none"):
        for axis in spec.axes:
            longest = max(f.period_px for f in spec.phase.of(axis))
            if longest < spec.pixels(axis) + EDGE_GAP_PX:
                out.append(
                    f"phase.frequencies ({axis}): the longest period, {longest:g} px, ends within {EDGE_GAP_PX} px of "
                    f"the {spec.pixels(axis)} {axis}' end: the first and last {axis} read alike within the phase "
                    "noise, and the edge pixels may land at the far side"
                )
    reasons = {k: v for k, v in counts.items() if v > 0 and k.startswith(("low_", "weak_", "unwrap_", "beyond_"))}
    detail = ", ".join(f"{k.replace('_', ' ')} {v}" for k, v in reasons.items())
    if lit and decoded < LEAST_DECODED * lit:
        out.append(
            f"only {decoded / lit:.0%} of the {lit} lit pixels decoded ({detail or 'no reason counted'}): the "
            "description's periods, steps, shift direction or frame order may not be what was projected"
        )
    for axis in spec.axes:
        beyond = counts.get(f"beyond_projector_{axis}", 0)
        if lit and beyond > MOST_BEYOND * lit:
            out.append(
                f"{beyond / lit:.0%} of the lit pixels ({beyond}) decode beyond the projector's {spec.pixels(axis)} "
                f"{axis}: the description's resolution, periods or code step may be wrong"
            )
    return out
