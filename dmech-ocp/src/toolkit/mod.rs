//! The planning toolkit on top of the transcriptions and the solver: a start from a
//! geometric path ([`kinematic_start`]), a solution carried to a finer mesh ([`refine`]),
//! and continuation and mesh sequencing ([`sequencing`]).

pub mod kinematic_start;
pub mod refine;
pub mod sequencing;
