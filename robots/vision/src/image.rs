//! Grey images.

/// A grey image, row-major, intensities 0-255 as `f32`.
#[derive(Clone, Debug, PartialEq)]
pub struct Gray {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Intensities.
    pub data: Vec<f32>,
}

impl Gray {
    /// Luminance (ITU-R BT.601 weights) of an RGB image; `None` unless `rgb` holds exactly
    /// `width x height x 3` bytes (a shorter buffer would make [`Gray::at`] read past its end).
    pub fn from_rgb(width: usize, height: usize, rgb: &[u8]) -> Option<Self> {
        if width.checked_mul(height)?.checked_mul(3)? != rgb.len() {
            return None;
        }
        let data = rgb
            .chunks_exact(3)
            .map(|p| 0.299 * p[0] as f32 + 0.587 * p[1] as f32 + 0.114 * p[2] as f32)
            .collect();
        Some(Self {
            width,
            height,
            data,
        })
    }

    /// The grey image a camera message carries: its grey levels as they are (`mono8`), or
    /// the luminance of its RGB ([`Gray::from_rgb`]); `None` unless its bytes are its
    /// width x height x channels.
    pub fn from_image(image: &hetsim_msgs::Image) -> Option<Self> {
        let (w, h) = (image.width as usize, image.height as usize);
        match image.encoding {
            hetsim_msgs::PixelEncoding::Rgb8 => Self::from_rgb(w, h, &image.data),
            hetsim_msgs::PixelEncoding::Mono8 => {
                (w.checked_mul(h)? == image.data.len()).then(|| Self {
                    width: w,
                    height: h,
                    data: image.data.iter().map(|&g| g as f32).collect(),
                })
            }
        }
    }

    /// The image at half resolution: each pixel the mean of a 2 x 2 block (pixel `i` of the
    /// result is centred on `2 i + 0.5` of this one).
    pub fn half(&self) -> Self {
        let (w, h) = (self.width / 2, self.height / 2);
        let mut data = Vec::with_capacity(w * h);
        for y in 0..h {
            let (a, b) = (
                &self.data[2 * y * self.width..][..2 * w],
                &self.data[(2 * y + 1) * self.width..][..2 * w],
            );
            data.extend(
                a.chunks_exact(2)
                    .zip(b.chunks_exact(2))
                    .map(|(p, q)| 0.25 * ((p[0] + p[1]) + (q[0] + q[1]))),
            );
        }
        Self {
            width: w,
            height: h,
            data,
        }
    }

    /// The intensity at integer `(x, y)`.
    #[inline]
    pub fn at(&self, x: usize, y: usize) -> f32 {
        self.data[y * self.width + x]
    }

    /// Bilinear intensity at `(x, y)`, if inside.
    pub fn sample(&self, x: f64, y: f64) -> Option<f32> {
        if x < 0.0 || y < 0.0 || x > (self.width - 1) as f64 || y > (self.height - 1) as f64 {
            return None;
        }
        let (x0, y0) = (x.floor() as usize, y.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(self.width - 1), (y0 + 1).min(self.height - 1));
        let (tx, ty) = ((x - x0 as f64) as f32, (y - y0 as f64) as f32);
        let top = self.at(x0, y0) * (1.0 - tx) + self.at(x1, y0) * tx;
        let bottom = self.at(x0, y1) * (1.0 - tx) + self.at(x1, y1) * tx;
        Some(top * (1.0 - ty) + bottom * ty)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hetsim_msgs::Pinhole;
    use nalgebra::Vector3;
    use rand::{RngExt, SeedableRng};

    #[test]
    fn a_buffer_that_is_not_its_size_makes_no_image() {
        // The example: 4 x 3 RGB needs 36 bytes; 35 or 37 would leave `at` reading
        // past the end or the rows misaligned.
        assert!(Gray::from_rgb(4, 3, &[0; 35]).is_none());
        assert!(Gray::from_rgb(4, 3, &[0; 37]).is_none());
        assert!(
            Gray::from_rgb(usize::MAX, 3, &[]).is_none(),
            "no overflowing product"
        );
        let g = Gray::from_rgb(4, 3, &[9; 36]).unwrap();
        assert_eq!((g.width, g.height, g.data.len()), (4, 3, 12));
        let mono = |bytes: usize| hetsim_msgs::Image {
            stamp_ns: 0,
            sensor: "c".into(),
            width: 4,
            height: 3,
            encoding: hetsim_msgs::PixelEncoding::Mono8,
            data: vec![7; bytes],
        };
        assert!(Gray::from_image(&mono(11)).is_none());
        assert_eq!(Gray::from_image(&mono(12)).unwrap().at(3, 2), 7.0);
    }

    #[test]
    fn project_back_project_round_trip_and_jacobian_match_finite_differences() {
        let cam = Pinhole {
            alpha_u: 700.0,
            alpha_v: 690.0,
            u0: 511.5,
            v0: 383.5,
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for _ in 0..1000 {
            let p = Vector3::new(
                rng.random_range(-20.0..20.0),
                rng.random_range(-20.0..20.0),
                rng.random_range(0.5..200.0),
            );
            let [u, v] = cam.project(&p).unwrap();
            let back = cam.back_project(u, v, p.z);
            assert!((back - p).norm() < 1e-9 * p.norm().max(1.0));
            let j = cam.project_jacobian(&p);
            for k in 0..3 {
                let h = 1e-6 * p.norm().max(1.0);
                let mut q = p;
                q[k] += h;
                let [u2, v2] = cam.project(&q).unwrap();
                let mut r = p;
                r[k] -= h;
                let [u1, v1] = cam.project(&r).unwrap();
                let (du, dv) = ((u2 - u1) / (2.0 * h), (v2 - v1) / (2.0 * h));
                assert!(
                    (du - j[0][k]).abs() < 1e-4 * (1.0 + j[0][k].abs()),
                    "du/dp{k}: {du} vs {}",
                    j[0][k]
                );
                assert!(
                    (dv - j[1][k]).abs() < 1e-4 * (1.0 + j[1][k].abs()),
                    "dv/dp{k}: {dv} vs {}",
                    j[1][k]
                );
            }
        }
    }

    #[test]
    fn world_points_seen_from_random_poses_round_trip() {
        use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion};
        let cam = Pinhole {
            alpha_u: 443.4,
            alpha_v: 443.4,
            u0: 255.5,
            v0: 191.5,
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for _ in 0..1000 {
            let world_from_camera = Isometry3::from_parts(
                Translation3::new(
                    rng.random_range(-100.0..100.0),
                    rng.random_range(-100.0..100.0),
                    rng.random_range(0.0..60.0),
                ),
                UnitQuaternion::from_euler_angles(
                    rng.random_range(-3.2..3.2),
                    rng.random_range(-1.5..1.5),
                    rng.random_range(-3.2..3.2),
                ),
            );
            // A point in front of the camera, placed through the camera, then forgotten.
            let local = Vector3::new(
                rng.random_range(-10.0..10.0),
                rng.random_range(-10.0..10.0),
                rng.random_range(1.0..150.0),
            );
            let world = world_from_camera * Point3::from(local);
            let seen = world_from_camera.inverse_transform_point(&world).coords;
            let [u, v] = cam.project(&seen).unwrap();
            let back = world_from_camera * Point3::from(cam.back_project(u, v, seen.z));
            assert!((back - world).norm() < 1e-9 * (1.0 + world.coords.norm()));
            // The Jacobian of the pixel with respect to the world point is J R^T.
            let j = nalgebra::Matrix2x3::from_fn(|r, c| cam.project_jacobian(&seen)[r][c])
                * world_from_camera
                    .rotation
                    .to_rotation_matrix()
                    .matrix()
                    .transpose();
            for k in 0..3 {
                let h = 1e-5 * (1.0 + seen.z);
                let mut step = Vector3::zeros();
                step[k] = h;
                let f = |p: Point3<f64>| {
                    let q = world_from_camera.inverse_transform_point(&p).coords;
                    nalgebra::Vector2::from(cam.project(&q).unwrap())
                };
                let numeric = (f(world + step) - f(world - step)) / (2.0 * h);
                let analytic = j.column(k);
                assert!(
                    (numeric - analytic).norm() < 1e-5 * (1.0 + analytic.norm()),
                    "{numeric} vs {analytic}"
                );
            }
        }
    }
}
