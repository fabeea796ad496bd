//! The SLAM stack's local level: points and line segments observed in each frame, updated in the local EKF map, and new ones initialized where the image has room.

use super::*;

impl SlamCore {
    pub(super) fn observe(&mut self, img: &Gray) {
        let sigma = self.params.sigma_px;
        let mut k = 0;
        while k < self.map.points.len() {
            let Some(predicted) = self.map.predict_point(&self.sensor, k, sigma) else {
                k += 1;
                continue;
            };
            let (pr, s) = &predicted;
            let inside = pr.pixel.x >= 6.0
                && pr.pixel.y >= 6.0
                && pr.pixel.x < img.width as f64 - 7.0
                && pr.pixel.y < img.height as f64 - 7.0;
            if !inside || s[(0, 0)].max(s[(1, 1)]).sqrt() > self.params.max_search_px {
                k += 1;
                continue;
            }
            self.map.points[k].searched += 1;
            let half = self.vo.half().expect("VO ran on this frame");
            let found = search_pyramid(
                img,
                half,
                &self.patches[&self.map.points[k].id],
                [pr.pixel.x, pr.pixel.y],
                [[s[(0, 0)], s[(0, 1)]], [s[(1, 0)], s[(1, 1)]]],
                9.21,
                0.8,
                3.0,
            );
            if let Some(m) = found {
                match self
                    .map
                    .update_predicted(k, &Vector2::new(m.x, m.y), &predicted, 9.21)
                {
                    Some(Update::Accepted) => {
                        self.map.points[k].found += 1;
                        self.updates.0 += 1;
                    }
                    Some(Update::Gated(_)) => self.updates.1 += 1,
                    None => {}
                }
            }
            k += 1;
        }
        if self.params.lines {
            self.observe_lines(img);
        }
        self.map.symmetrize();
        for id in self.map.prune(self.params.min_searches) {
            self.patches.remove(&id);
        }
    }

    /// The camera's pose in the local map.
    pub(super) fn camera_pose(&self) -> Pose {
        self.map.pose() * self.body_from_camera
    }

    /// Line `j`'s segment predicted into the image and clipped to it.
    pub(super) fn predict_segment(&self, j: usize, img: &Gray) -> Option<Segment> {
        let [p, q] = self.map.line_endpoints(j);
        let seg = segments::project_segment(
            &self.sensor.camera,
            &self.camera_pose(),
            &p.into(),
            &q.into(),
            0.5,
        )?;
        let margin = 3.0;
        seg.clipped(
            [margin, margin],
            [
                img.width as f64 - 1.0 - margin,
                img.height as f64 - 1.0 - margin,
            ],
        )
    }

    /// Tracks the lines and updates the map with them.
    pub(super) fn observe_lines(&mut self, img: &Gray) {
        let sigma = self.params.sigma_px;
        let tracking = segments::TrackParams::default();
        self.seen_segments.clear();
        for j in 0..self.map.lines.len() {
            let Some(predicted) = self.predict_segment(j, img) else {
                continue;
            };
            if predicted.length() < 4.0 * tracking.spacing_px {
                continue;
            }
            self.seen_segments.push(predicted);
            let (a, b) = (Vector2::from(predicted.a), Vector2::from(predicted.b));
            let Some(pr) = self.map.predict_line(&self.sensor, j, &a, &b, sigma) else {
                continue;
            };
            let spread = pr.s[(0, 0)].max(pr.s[(1, 1)]).sqrt();
            if spread > self.params.max_search_px {
                continue;
            }
            self.map.lines[j].searched += 1;
            let params = segments::TrackParams {
                search_px: (3.0 * spread).clamp(3.0, tracking.search_px),
                ..tracking
            };
            let Some(seen) = segments::track(img, &predicted, &params) else {
                continue;
            };
            let (e1, e2) = (Vector2::from(seen.a), Vector2::from(seen.b));
            match self.map.update_line(&self.sensor, j, &e1, &e2, sigma, 9.21) {
                Some(Update::Accepted) => {
                    self.map.lines[j].found += 1;
                    self.map.extend_line(&self.sensor, j, &e1, &e2);
                    *self.seen_segments.last_mut().expect("pushed above") = seen;
                    self.count("line_observations_used", 1);
                }
                Some(Update::Gated(_)) => self.count("line_observations_gated", 1),
                None => {}
            }
        }
    }

    /// New lines from detected segments that no tracked line covers.
    pub(super) fn add_lines(&mut self, img: &Gray) {
        if self.seen_segments.len() >= self.params.max_visible_lines
            // The frames before this one are in the trajectory.
            || self.trajectory.len() % self.params.line_detect_period as usize != 0
        {
            return;
        }
        let detect = segments::DetectParams {
            min_length: self.params.min_line_px * img.width as f64 / 1024.0,
            scale: self.params.line_detect_scale,
            ..Default::default()
        };
        let mut found = segments::detect(img, &detect);
        // The longest first.
        found.sort_by(|x, y| y.length().total_cmp(&x.length()));
        for seg in found {
            if self.seen_segments.len() >= self.params.max_visible_lines
                || self.map.landmarks() >= self.params.max_landmarks
            {
                break;
            }
            if self.seen_segments.iter().any(|t| covers(t, &seg)) {
                continue;
            }
            let id = self.next_id;
            let (a, b) = (Vector2::from(seg.a), Vector2::from(seg.b));
            let added = self.map.add_line(
                &self.sensor,
                &a,
                &b,
                self.params.sigma_px,
                &self.params.line_prior,
                id,
            );
            if added.is_some() {
                self.next_id += 1;
                self.seen_segments.push(seg);
                self.count("lines_initialized", 1);
            }
        }
    }

    pub(super) fn add_points(&mut self, img: &Gray) {
        // Where the current points are seen, for the 3 x 3 partition.
        let tracked: Vec<[f64; 2]> = (0..self.map.points.len())
            .filter_map(|k| {
                crate::idp::project(
                    &self.sensor,
                    &self.map.position(),
                    &self.map.quaternion(),
                    &self.map.point(k),
                )
                .map(|p| [p.pixel.x, p.pixel.y])
            })
            .filter(|p| {
                p[0] >= 0.0 && p[1] >= 0.0 && p[0] < img.width as f64 && p[1] < img.height as f64
            })
            .collect();
        // VO detected this image's corners above 0.005 of the largest response; the map
        // takes those above 0.01 of it (what `harris::detect(img, 0.01, 8)` gives).
        let (all, max) = self.vo.corners();
        let corners: Vec<Corner> = all
            .iter()
            .filter(|c| c.response >= 0.01 * max)
            .copied()
            .collect();
        let chosen = select_new(
            &corners,
            img.width,
            img.height,
            &tracked,
            self.params.per_region,
            15.0,
        );
        for c in chosen {
            if self.map.landmarks() >= self.params.max_landmarks {
                break;
            }
            let half = self.vo.half().expect("VO ran on this frame");
            let Some(patch) = Template::at(img, half, c.x, c.y) else {
                continue;
            };
            let id = self.next_id;
            self.next_id += 1;
            self.map.add_point(
                &self.sensor,
                &Vector2::new(c.x as f64, c.y as f64),
                self.params.sigma_px,
                self.params.rho_init,
                self.params.sigma_rho,
                id,
            );
            self.patches.insert(id, patch);
        }
    }
}
