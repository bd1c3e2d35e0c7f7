//! The guidance algorithm: distance and heading errors `(e_d, e_θ)` of an estimated pose
//! against the plan's pose, the pose part of the LQ controller's error state.

/// Look-ahead length (m) over which a lateral offset is turned into a heading correction.
pub const LOOK_AHEAD: f64 = 0.15;
/// Planned speed (m/s) below which the lateral correction fades out (the sign of the
/// correction depends on the direction of travel, and at rest no heading removes it).
pub const FADE_SPEED: f64 = 0.05;

/// `θ` wrapped to `(−π, π]`.
pub fn wrap(a: f64) -> f64 {
    let w = a.rem_euclid(2.0 * std::f64::consts::PI);
    if w > std::f64::consts::PI {
        w - 2.0 * std::f64::consts::PI
    } else {
        w
    }
}

/// Errors of the pose `(x, y, θ)` against the plan's `(x_d, y_d, θ_d)` moving at `v_d`:
/// `e_d` along the planned heading, `e_θ = wrap(θ − θ_d) + atan(e_lat / L)·tanh(v_d / v₀)`
/// with the lateral offset `e_lat` to the left of the planned heading: driving `e_θ` to
/// zero steers back onto the path.
pub fn errors(pose: [f64; 3], plan: [f64; 3], v_d: f64) -> (f64, f64) {
    let (dx, dy) = (pose[0] - plan[0], pose[1] - plan[1]);
    let (s, c) = plan[2].sin_cos();
    let e_d = c * dx + s * dy;
    let e_lat = -s * dx + c * dy;
    let e_theta = wrap(pose[2] - plan[2]) + (e_lat / LOOK_AHEAD).atan() * (v_d / FADE_SPEED).tanh();
    (e_d, e_theta)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors_in_the_plan_frame() {
        // Plan heading +y; the robot 1 cm ahead along it and 2 cm to its right (+x).
        let (ed, et) = errors(
            [0.02, 0.01, std::f64::consts::FRAC_PI_2],
            [0.0, 0.0, std::f64::consts::FRAC_PI_2],
            0.0,
        );
        assert!((ed - 0.01).abs() < 1e-15 && et.abs() < 1e-15);
        // Moving forward, right of the path: e_θ < 0, so the controller turns left.
        let (_, et) = errors(
            [0.02, 0.0, std::f64::consts::FRAC_PI_2],
            [0.0, 0.0, std::f64::consts::FRAC_PI_2],
            1.0,
        );
        assert!(et < 0.0);
        assert!((wrap(3.0 * std::f64::consts::PI) - std::f64::consts::PI).abs() < 1e-12);
    }
}
