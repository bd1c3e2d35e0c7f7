//! How the stage vectors are laid out, and splitting them.

use nalgebra::SVector;

/// Sizes of a transcription's stage vectors for a system with `np` group coordinates,
/// `ns` shape coordinates and `nu` inputs, and which shape coordinates the state leaves
/// out (`ignored`, bit `i` for `s_i`).
///
/// An ignorable shape coordinate is one the stage functions do not read: the equations
/// of motion do not depend on it (the reduced Lagrangian only through a total time
/// derivative; the connection and the forcing not at all) and neither do the cost, the
/// inequalities or the conditions. Its velocity stays in the state and the decisions; its
/// position is not carried (the stage functions see it at zero), so the state is smaller
/// by one per ignorable coordinate. Wheel angles and motor charges are often such: a
/// robot on a level floor whose forces read only their rates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Layout {
    /// The pose's coordinates, `coords(g)` (SE(2): 3).
    pub np: usize,
    /// The shape coordinates.
    pub ns: usize,
    /// The inputs.
    pub nu: usize,
    /// The shape positions the state leaves out, bit `i` for `s_i`.
    pub ignored: u32,
}

/// A layout that does not fit the sizes a transcription was given.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum LayoutError {
    /// `NX` or `NW` is not what the layout holds.
    #[error(
        "stage sizes NX = {nx}, NW = {nw} do not match the system: NX must be {expected_nx} \
         (coords {np} + {carried} carried shape + {ns} + {nu}), NW must be {expected_nw}"
    )]
    Sizes {
        /// The given state size.
        nx: usize,
        /// The given decision size.
        nw: usize,
        /// The layout's state size.
        expected_nx: usize,
        /// The transcription's decision size.
        expected_nw: usize,
        /// The layout's pose coordinates.
        np: usize,
        /// The shape positions the layout carries.
        carried: usize,
        /// The shape coordinates.
        ns: usize,
        /// The inputs.
        nu: usize,
    },
    /// `NP` is not the group's number of coordinates.
    #[error("NP = {given} but the group has {group} coordinates")]
    PoseCoordinates {
        /// The given `NP`.
        given: usize,
        /// `coords(g)`'s length.
        group: usize,
    },
    /// The layout was made for another system.
    #[error("the layout has {layout} pose, shape and input sizes, the system {system}")]
    System {
        /// The layout's `(np, ns, nu)`.
        layout: String,
        /// The system's.
        system: String,
    },
    /// An ignored shape coordinate out of range.
    #[error("ignorable shape coordinate {index} of {ns} (at most 32 shape coordinates)")]
    Ignored {
        /// The coordinate.
        index: usize,
        /// The shape coordinates.
        ns: usize,
    },
}

/// `Err` unless `NP` is the group's number of coordinates `group`.
pub(crate) fn check_pose_coordinates<const NP: usize>(group: usize) -> Result<(), LayoutError> {
    if NP == group {
        Ok(())
    } else {
        Err(LayoutError::PoseCoordinates { given: NP, group })
    }
}

impl Layout {
    /// Every shape coordinate carried.
    pub const fn new(np: usize, ns: usize, nu: usize) -> Self {
        Layout {
            np,
            ns,
            nu,
            ignored: 0,
        }
    }

    /// The same sizes with the shape coordinates `ignored` left out of the state. Panics
    /// on a coordinate out of range (at most 32 shape coordinates); [`Layout::try_ignoring`]
    /// returns the error instead.
    pub fn ignoring(self, ignored: &[usize]) -> Self {
        self.try_ignoring(ignored).unwrap_or_else(|e| panic!("{e}"))
    }

    /// [`Layout::ignoring`], `Err` on a coordinate out of range.
    pub fn try_ignoring(self, ignored: &[usize]) -> Result<Self, LayoutError> {
        let mut mask = 0u32;
        for &i in ignored {
            if i >= self.ns || i >= 32 {
                return Err(LayoutError::Ignored {
                    index: i,
                    ns: self.ns,
                });
            }
            mask |= 1 << i;
        }
        Ok(Layout {
            ignored: mask,
            ..self
        })
    }

    /// Whether the state leaves `s_i` out.
    pub fn is_ignored(&self, i: usize) -> bool {
        self.ignored >> i & 1 == 1
    }

    /// Shape positions the state carries.
    pub fn ns_kept(&self) -> usize {
        self.ns - self.ignored.count_ones() as usize
    }

    /// State size of both transcriptions: `coords(g)`, the carried part of `s`, a
    /// velocity, `u_{k−1}`.
    pub fn nx(&self) -> usize {
        self.np + self.ns_kept() + self.ns + self.nu
    }
    /// Offsets of the carried `s`, the velocity and `u_{k−1}` in the state.
    pub fn s_at(&self) -> usize {
        self.np
    }
    /// Offset of the velocity in the state.
    pub fn v_at(&self) -> usize {
        self.np + self.ns_kept()
    }
    /// Offset of `u_{k−1}` in the state.
    pub fn u_at(&self) -> usize {
        self.v_at() + self.ns
    }

    /// Where `s_i` sits in the state, `None` if it is ignored.
    pub fn shape_slot(&self, i: usize) -> Option<usize> {
        if self.is_ignored(i) {
            return None;
        }
        let below = (self.ignored & ((1u32 << i) - 1)).count_ones() as usize;
        Some(self.s_at() + i - below)
    }

    /// `s` of a state, its ignored coordinates at zero.
    pub fn shape<T: dmech_lie::Real, const NX: usize, const NS: usize>(
        &self,
        x: &SVector<T, NX>,
    ) -> SVector<T, NS> {
        SVector::<T, NS>::from_fn(|i, _| match self.shape_slot(i) {
            Some(at) => x[at],
            None => T::zero(),
        })
    }

    /// Write the carried part of `s` into a state.
    pub fn set_shape<T: nalgebra::Scalar + Copy, const NX: usize, const NS: usize>(
        &self,
        x: &mut SVector<T, NX>,
        s: &SVector<T, NS>,
    ) {
        for i in 0..NS {
            if let Some(at) = self.shape_slot(i) {
                x[at] = s[i];
            }
        }
    }

    /// `Err` unless the state size `NX` is the layout's and the decision size `NW` is
    /// `nw_expected` (the transcription's).
    pub fn fits<const NX: usize, const NW: usize>(
        &self,
        nw_expected: usize,
    ) -> Result<(), LayoutError> {
        if NX == self.nx() && NW == nw_expected {
            return Ok(());
        }
        Err(self.sizes_error(NX, NW, nw_expected))
    }

    fn sizes_error(&self, nx: usize, nw: usize, nw_expected: usize) -> LayoutError {
        LayoutError::Sizes {
            nx,
            nw,
            expected_nx: self.nx(),
            expected_nw: nw_expected,
            np: self.np,
            carried: self.ns_kept(),
            ns: self.ns,
            nu: self.nu,
        }
    }

    /// Panics unless `nx` is the layout's state size and `nw` is `nw_expected`: for the
    /// stage functions' own callers, whose sizes are a programming error when they
    /// disagree ([`Layout::fits`] is the checked form).
    pub fn check(&self, nx: usize, nw: usize, nw_expected: usize) {
        if nx != self.nx() || nw != nw_expected {
            panic!("{}", self.sizes_error(nx, nw, nw_expected));
        }
    }

    /// `Err` unless the layout has the pose, shape and input sizes of `system`'s.
    pub fn agrees_with(&self, system: &Layout) -> Result<(), LayoutError> {
        let sizes = |l: &Layout| (l.np, l.ns, l.nu);
        if sizes(self) == sizes(system) {
            return Ok(());
        }
        Err(LayoutError::System {
            layout: format!("{:?}", sizes(self)),
            system: format!("{:?}", sizes(system)),
        })
    }
}

/// A fixed-size sub-vector.
pub fn segment<T: nalgebra::Scalar + Copy, const N: usize, const M: usize>(
    x: &SVector<T, N>,
    at: usize,
) -> SVector<T, M> {
    SVector::<T, M>::from_fn(|i, _| x[at + i])
}
