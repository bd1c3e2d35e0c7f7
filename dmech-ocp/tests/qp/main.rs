//! `dmech_ocp::qp` on random stage QPs: against clarabel on the same QP written out as one
//! sparse program (`clarabel_oracle`), the KKT conditions on our solution, warm starts, and
//! the statuses of infeasible and unbounded QPs (`statuses`), the text form (`text`). Shared: the random QPs
//! (`random`) and their clarabel form (`oracle`).

// The oracle's assembly indexes several per-stage arrays in step.
#![allow(clippy::needless_range_loop)]

mod clarabel_oracle;
mod oracle;
mod random;
mod statuses;
mod text;
