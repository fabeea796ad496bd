//! Survey routes.

/// A lawnmower (boustrophedon) route over the rectangle whose centre line runs from `from` to
/// `to` (world xy) and which is `width_m` wide, at constant `altitude_m`.
///
/// Legs run parallel to `from -> to`, `spacing_m` apart, starting on the left edge (seen from
/// `from` looking at `to`); consecutive legs alternate direction. Returns the leg end points in
/// flying order. The number of legs is `floor(width / spacing) + 1`.
pub fn lawnmower(
    from: [f64; 2],
    to: [f64; 2],
    width_m: f64,
    spacing_m: f64,
    altitude_m: f64,
) -> Vec<[f64; 3]> {
    let (dx, dy) = (to[0] - from[0], to[1] - from[1]);
    let len = dx.hypot(dy);
    if len <= 0.0 || spacing_m <= 0.0 || width_m < 0.0 {
        return vec![[from[0], from[1], altitude_m]];
    }
    let (ux, uy) = (dx / len, dy / len);
    let (lx, ly) = (-uy, ux); // left of the direction of travel
    let legs = (width_m / spacing_m).floor() as usize + 1;
    let mut points = Vec::with_capacity(2 * legs);
    for k in 0..legs {
        let offset = width_m / 2.0 - k as f64 * spacing_m;
        let a = [from[0] + lx * offset, from[1] + ly * offset, altitude_m];
        let b = [to[0] + lx * offset, to[1] + ly * offset, altitude_m];
        if k % 2 == 0 {
            points.extend([a, b]);
        } else {
            points.extend([b, a]);
        }
    }
    points
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn legs_are_parallel_spaced_and_alternate() {
        let route = lawnmower([0.0, 0.0], [100.0, 0.0], 40.0, 20.0, 40.0);
        assert_eq!(route.len(), 6);
        assert_eq!(route[0], [0.0, 20.0, 40.0]);
        assert_eq!(route[1], [100.0, 20.0, 40.0]);
        assert_eq!(route[2], [100.0, 0.0, 40.0]);
        assert_eq!(route[3], [0.0, 0.0, 40.0]);
        assert_eq!(route[5], [100.0, -20.0, 40.0]);
    }
}
