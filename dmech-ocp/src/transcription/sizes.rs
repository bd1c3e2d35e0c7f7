//! The sizes of a transcription's stage vectors, derived from the robot's own.
//!
//! A robot states its sizes once: `DOF`, `NS` and `NU` in its
//! [`PrincipalKinematicSystem`](dmech::PrincipalKinematicSystem) impl, `NP` (the group's
//! coordinates) and `NC` (the path constraints) in its
//! [`PlanningProblem`](super::PlanningProblem) impl. The solver's state and decision sizes
//! follow from them: with every shape position carried,
//!
//! ```text
//! NX = NP + 2 NS + NU      (pose coordinates, shape, a velocity, the previous input)
//! NW = NS + NU             (variational: v_k and u_k; Runge–Kutta decides u_k alone)
//! ```
//!
//! Stable Rust cannot compute `NP + 2 NS + NU` from generic constants, so the sums are a
//! table: [`Dims<NP, NS, NU>`](Dims) implements [`StageSizes<NX, NW>`](StageSizes) for
//! every robot with `NP ≤ 7` pose coordinates (SE(3) has 7), `NS ≤ 10` shape coordinates
//! and `NU ≤ 6` inputs. With concrete sizes the compiler finds the one entry and infers
//! `NX` and `NW`, so that `VarIntTranscription::new(&robot, problem, h, scheme)` and
//! `Solver::new(&transcription, options)` need no sizes at all. Generic code over the
//! sizes (or a robot beyond the table, or a state that leaves ignorable shape positions
//! out) names `NX` and `NW` and uses the transcriptions' `with_layout` constructors, which
//! check them against the layout.

/// The sizes a robot states: `NP` pose coordinates, `NS` shape coordinates, `NU` inputs.
/// A type-level key of the [`StageSizes`] table; it has no values.
pub struct Dims<const NP: usize, const NS: usize, const NU: usize>;

/// The stage sizes of a transcription whose state carries every shape position:
/// `NX = NP + 2 NS + NU` and, for the variational transcriptions, `NW = NS + NU`.
/// Implemented by [`Dims`] over the table's range (module documentation).
pub trait StageSizes<const NX: usize, const NW: usize> {}

macro_rules! stage_sizes {
    ([$($np:literal)*] $nss:tt $nus:tt) => { $( stage_sizes!(@ns $np $nss $nus); )* };
    (@ns $np:literal [$($ns:literal)*] $nus:tt) => { $( stage_sizes!(@nu $np $ns $nus); )* };
    (@nu $np:literal $ns:literal [$($nu:literal)*]) => {
        $( impl StageSizes<{ $np + 2 * $ns + $nu }, { $ns + $nu }> for Dims<$np, $ns, $nu> {} )*
    };
}

stage_sizes!([1 2 3 4 5 6 7] [0 1 2 3 4 5 6 7 8 9 10] [0 1 2 3 4 5 6]);

#[cfg(test)]
mod tests {
    use super::*;

    fn sizes<const NP: usize, const NS: usize, const NU: usize, const NX: usize, const NW: usize>(
    ) -> (usize, usize)
    where
        Dims<NP, NS, NU>: StageSizes<NX, NW>,
    {
        (NX, NW)
    }

    #[test]
    fn the_table_infers_the_layout_sums() {
        // SE(2) with two shape coordinates and two inputs; SE(3), the table's corners.
        assert_eq!(sizes::<3, 2, 2, _, _>(), (3 + 4 + 2, 4));
        assert_eq!(sizes::<7, 10, 6, _, _>(), (7 + 20 + 6, 16));
        assert_eq!(sizes::<1, 0, 0, _, _>(), (1, 0));
    }
}
