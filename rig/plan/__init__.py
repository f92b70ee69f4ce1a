"""Planning: where to put heads (`rig.plan.views`, casts rays with the simulator) and which rings
to project (`rig.plan.ring_spacing`, from a pilot scan's curvature). Import the module you need: the view
planner loads the simulator, the ring planner must not."""
