//! Motion: trajectories between poses and direct-stroke moves, hardware-free
//! (in the spirit of `ramp-maker`: the profile, not the drive).
//!
//! * [`ramp`]: the trapezoidal profile of a path parameter over whole control cycles
//!   ([`CYCLE_S`]), closed form in the cycle count, with a stop to rest at the
//!   acceleration limit.
//! * [`trajectory`]: coordinated moves on the straight line between two poses; the
//!   profile's rate and acceleration are derived from per-slider speed and acceleration
//!   limits through the strokes sampled along the path.
//! * [`stroke`]: one slider by a stroke, no kinematics (recovery).
//! * [`fine`]: closed-loop fine positioning on the slider encoders after a path, and
//!   the in-position rule that ends a move.
//! * [`limiter`]: the output stage, every command's per-cycle step bounded by the speed
//!   and acceleration limits in force, independent of the geometry and the planner.
//!
//! Per cycle the controller calls `setpoint(cycle)` with the cycle count since the move
//! began (a few tens of instructions), turns the pose into strokes by IK and commands
//! the drives. Nothing here allocates or panics.
//!
//! Error codes (family 0x06xx): [`MotionError`] 0x0601.., [`StrokeMoveError`] 0x0611...

pub mod fine;
pub mod limiter;
pub mod ramp;
pub mod stroke;
pub mod trajectory;

pub use limiter::{LimitKind, OutputLimiter, StepLimits};
pub use ramp::{Ramp, RampError, RampSample, CYCLE_S, MAX_MOVE_CYCLES};
pub use stroke::{
    DirectStrokeLimits, StrokeMove, StrokeMoveError, StrokeSetpoint,
    DEFAULT_DIRECT_ACCEL_MM_PER_S2, DEFAULT_DIRECT_MAX_DELTA_MM, DEFAULT_DIRECT_SPEED_MM_PER_S,
};
pub use trajectory::{
    MotionError, MotionLimits, PathBounds, PlanStart, Setpoint, Trajectory, TrajectoryPlanner,
    DEFAULT_MAX_ACCEL_MM_PER_S2, DEFAULT_MAX_SPEED_MM_PER_S, PATH_SAMPLE_INTERVALS,
};
