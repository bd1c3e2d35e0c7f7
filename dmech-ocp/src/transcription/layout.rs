//! How the stage vectors are laid out, and splitting them.

use nalgebra::SVector;

/// Sizes of a transcription's stage vectors for a system with `nc` group coordinates,
/// `ns` shape coordinates and `nu` inputs, and which shape coordinates the state leaves
/// out (`ignored`, bit `i` for `s_i`).
///
/// An ignorable shape coordinate is one the stage functions do not read: the equations
/// of motion do not depend on it (the reduced Lagrangian only through a total time
/// derivative; the connection and the forcing not at all) and neither do the cost, the
/// inequalities or the conditions. Its velocity stays in the state and the decisions; its
/// position is not carried (the stage functions see it at zero), so the state is smaller
/// by one per ignorable coordinate. The WIP's wheel angles and charges are such.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Layout {
    pub nc: usize,
    pub ns: usize,
    pub nu: usize,
    pub ignored: u32,
}

impl Layout {
    /// Every shape coordinate carried.
    pub const fn new(nc: usize, ns: usize, nu: usize) -> Self {
        Layout {
            nc,
            ns,
            nu,
            ignored: 0,
        }
    }

    /// The same sizes with the shape coordinates `ignored` left out of the state.
    pub fn ignoring(self, ignored: &[usize]) -> Self {
        let mut mask = 0u32;
        for &i in ignored {
            assert!(
                i < self.ns && i < 32,
                "ignorable shape coordinate {i} of {} (at most 32 shape coordinates)",
                self.ns
            );
            mask |= 1 << i;
        }
        Layout {
            ignored: mask,
            ..self
        }
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
        self.nc + self.ns_kept() + self.ns + self.nu
    }
    /// Offsets of the carried `s`, the velocity and `u_{k−1}` in the state.
    pub fn s_at(&self) -> usize {
        self.nc
    }
    pub fn v_at(&self) -> usize {
        self.nc + self.ns_kept()
    }
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

    /// Check that const-generic sizes agree with the system; a mismatch is a programming
    /// error, reported with both sides.
    pub fn check(&self, nx: usize, nw: usize, nw_expected: usize) {
        assert!(
            nx == self.nx() && nw == nw_expected,
            "stage sizes NX = {nx}, NW = {nw} do not match the system: NX must be {} \
             (coords {} + {} carried shape + {} + {}), NW must be {nw_expected}",
            self.nx(),
            self.nc,
            self.ns_kept(),
            self.ns,
            self.nu
        );
    }
}

/// A fixed-size sub-vector.
pub fn segment<T: nalgebra::Scalar + Copy, const N: usize, const M: usize>(
    x: &SVector<T, N>,
    at: usize,
) -> SVector<T, M> {
    SVector::<T, M>::from_fn(|i, _| x[at + i])
}
