"""Planning: where to put heads (`rig.plan.views`, casts rays with the simulator) and which rings
to project (`rig.plan.ring_spacing`, from a pilot scan's curvature). Import the module you need: the view
planner loads the simulator, the ring planner must not."""

from rig.lazy import face

# The names other packages use, each imported from its module when first read (rig.lazy.face).
_LAZY = {
    "PilotView": "ring_spacing",
    "RingPlan": "ring_plan",
    "confirm_on_bench": "views",
    "disagreement": "signature",
    "pilot_views": "ring_plan",
    "plan_rings": "ring_plan",
    "plan_views": "views",
    "rehearsal_progress": "rehearsal",
}
__getattr__, __dir__ = face(__name__, _LAZY)

__all__ = [
    "PilotView",
    "RingPlan",
    "confirm_on_bench",
    "disagreement",
    "pilot_views",
    "plan_rings",
    "plan_views",
    "rehearsal_progress",
]
