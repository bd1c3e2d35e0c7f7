//! A system whose own parameters the diagnosis leaves at their values (`Param = f64`), seen
//! as a system of any fit scalar, so that [`crate::SystemPlant`] can observe it: its
//! effects then enter through what the observation adds (`ObservedSystem::shape_force`,
//! `input`, `measure`) and the generic hypotheses, not through the system's parameters.

use crate::FitScalar;
use dmech::{Lift, PrincipalKinematicSystem};
use dmech_lie::Real;
use nalgebra::{SMatrix, SVector};
use std::marker::PhantomData;

/// `system` with its `f64` parameters, as a system whose parameter scalar is `T`.
#[derive(Clone, Copy, Debug)]
pub struct FixedParams<S, T> {
    /// The system.
    pub system: S,
    scalar: PhantomData<T>,
}

impl<S, T> FixedParams<S, T> {
    /// `system` for a fit in scalar `T`.
    pub fn new(system: S) -> Self {
        FixedParams {
            system,
            scalar: PhantomData,
        }
    }
}

impl<S, T, const DOF: usize, const NS: usize, const NU: usize> PrincipalKinematicSystem<DOF, NS, NU>
    for FixedParams<S, T>
where
    S: PrincipalKinematicSystem<DOF, NS, NU, Param = f64>,
    T: FitScalar,
{
    type Param = T;
    type Group<U: Real> = S::Group<U>;

    fn reduced_lagrangian<U: Lift<T>>(
        &self,
        s: &SVector<U, NS>,
        v: &SVector<U, NS>,
        xi: &SVector<U, DOF>,
    ) -> U {
        self.system.reduced_lagrangian(s, v, xi)
    }
    fn connection<U: Lift<T>>(&self, s: &SVector<U, NS>) -> SMatrix<U, DOF, NS> {
        self.system.connection(s)
    }
    fn ignorable_shape(&self) -> &[usize] {
        self.system.ignorable_shape()
    }
    fn forcing<U: Lift<T>>(
        &self,
        s: &SVector<U, NS>,
        v: &SVector<U, NS>,
        u: &SVector<U, NU>,
    ) -> SVector<U, NS> {
        self.system.forcing(s, v, u)
    }
    #[allow(clippy::type_complexity)]
    fn closed_form_lagrangian_gradient<U: Lift<T>>(
        &self,
        s: &SVector<U, NS>,
        v: &SVector<U, NS>,
        xi: &SVector<U, DOF>,
    ) -> Option<(SVector<U, NS>, SVector<U, NS>, SVector<U, DOF>)> {
        self.system.closed_form_lagrangian_gradient(s, v, xi)
    }
    fn closed_form_acceleration<U: Lift<T>>(
        &self,
        s: &SVector<U, NS>,
        v: &SVector<U, NS>,
        u: &SVector<U, NU>,
    ) -> Option<SVector<U, NS>> {
        self.system.closed_form_acceleration(s, v, u)
    }
}
