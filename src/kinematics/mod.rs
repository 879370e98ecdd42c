//! Kinematics of the 6-PSS platform, generic over the float type ([`Real`]): the firmware
//! instantiates it in `f32`, the ground tools and the simulated plant in `f64`.
//!
//! * [`geometry`]: legs, home position, limits (`f64` parameters -> working geometry).
//! * [`pose`]: pose convention `R = Rz(gamma) Ry(beta) Rx(alpha)`, `R - I` without cancellation.
//! * [`ik`]: pose -> strokes, formulated relative to the home pose for f32 accuracy.
//! * [`fk`]: strokes -> pose, Newton-Raphson with the analytic Jacobian.
//! * [`workspace`]: every reason a pose is refused, without motion.
//! * [`frames`]: the operator's pivot and user frame, mapped to and from the internal pose.
//! * [`linalg`]: the 6x6 Newton solve, using the Jacobian's structure.
//!
//! Joint positions, rod vectors and rotations are nalgebra's fixed-size `Vector3` and
//! `Matrix3` (the ground tools' vocabulary); this costs no instruction and no byte on
//! the target against plain arrays (measured, docs/kinematics.md). The
//! 6x6 solve is our own: it uses the Jacobian's structure, and nalgebra's LU measured
//! 1.6 times the FK's instructions on the target.

pub mod fk;
pub mod frames;
pub mod geometry;
pub mod ik;
pub mod linalg;
pub mod pose;
pub mod real;
pub mod workspace;

pub use fk::{fk, FkConfig, FkError, FkSolution};
pub use frames::Frames;
pub use geometry::{
    Geometry, GeometryError, GeometryParams, LegParams, StrokeLimits, WorkspaceLimits, LEGS,
};
pub use ik::{ik, IkError};
pub use pose::Pose;
pub use real::Real;
pub use workspace::{check, Refusals};
