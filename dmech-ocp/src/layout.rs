//! How the stage vectors are laid out, and splitting them.

use nalgebra::SVector;

/// Sizes of a transcription's stage vectors for a system with `nc` group coordinates,
/// `ns` shape coordinates and `nu` inputs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Layout {
    pub nc: usize,
    pub ns: usize,
    pub nu: usize,
}

impl Layout {
    /// State size of both transcriptions: `coords(g)`, `s`, a velocity, `u_{k−1}`.
    pub fn nx(&self) -> usize {
        self.nc + 2 * self.ns + self.nu
    }
    /// Offsets of `s`, the velocity and `u_{k−1}` in the state.
    pub fn s_at(&self) -> usize {
        self.nc
    }
    pub fn v_at(&self) -> usize {
        self.nc + self.ns
    }
    pub fn u_at(&self) -> usize {
        self.nc + 2 * self.ns
    }
    /// Check that const-generic sizes agree with the system; a mismatch is a programming
    /// error, reported with both sides.
    pub fn check(&self, nx: usize, nw: usize, nw_expected: usize) {
        assert!(
            nx == self.nx() && nw == nw_expected,
            "stage sizes NX = {nx}, NW = {nw} do not match the system: NX must be {} \
             (coords {} + 2·{} + {}), NW must be {nw_expected}",
            self.nx(),
            self.nc,
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
