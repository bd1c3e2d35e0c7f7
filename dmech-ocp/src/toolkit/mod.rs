//! The planning toolkit on top of the transcriptions and the solver: a start from a
//! geometric path ([`kinematic_start`]), a solution carried to a finer mesh ([`refine`]),
//! continuation and mesh sequencing ([`sequencing`]), a plan replayed through its
//! integrator ([`replay`]), and all of it in one call ([`plan`]).

pub mod kinematic_start;
pub mod plan;
pub mod refine;
pub mod replay;
pub mod sequencing;
