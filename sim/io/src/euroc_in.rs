//! A EuRoC dataset (`mav0/cam0`, `cam1`, optionally `state_groundtruth_estimate0`) as stereo
//! input for one robot's VO and SLAM: `cam0` is the bench's left camera, `cam1` its right.
//!
//! The robot file describes the bench the robot software assumes; each camera's `sensor.yaml`
//! must agree with it (resolution, pinhole intrinsics, no distortion: hetsim's VO takes
//! rectified images), or replay refuses the dataset naming the file and the field. Stamps are
//! used as they are when they are sim times (hetsim's own dumps); a dataset stamped with wall
//! time (the first stamp more than a day) is shifted to start at its first image. Each image
//! reaches the robot at the tick nearest its stamp; replay ends one tick after the last image
//! (or earlier, at the scenario's duration or `--duration`).
//!
//! Every row of `data.csv` is checked and every image it lists must exist before replay
//! starts; a bad row, a missing image, two images on one tick, a ground-truth row that is
//! not a finite pose, or an image of another size is refused with the file and row.
//! Of `T_BS`, only the two cameras' distance is checked against the bench's baseline; the
//! bench's extrinsics are the robot file's, and a dataset whose cameras are not the
//! rectified, parallel pair the robot file describes replays wrong. Real
//! EuRoC sequences (752 x 480 with radial-tangential distortion) are refused until they are
//! rectified. A dataset's ground truth becomes the robot's oracle where its robot file
//! declares one (the pilot's truth), in the dataset's own world frame.

use hetsim_engine::replay::{Event, Logged, Recording, ReplayError};
use hetsim_engine::RecordedOutcome;
use hetsim_msgs::{Image, PixelEncoding, SensorMsg};
use std::collections::VecDeque;
use std::path::{Path, PathBuf};

/// The bench the robot file describes.
#[derive(Clone, Debug, PartialEq)]
pub struct BenchSpec {
    /// The robot replayed into.
    pub robot: String,
    /// The bench's name (images go to `<robot>/<bench>/left|right`).
    pub bench: String,
    /// Image size, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Pinhole intrinsics `[fu, fv, cu, cv]`.
    pub intrinsics: [f64; 4],
    /// The stereo baseline, metres.
    pub baseline_m: f64,
    /// The tick, nanoseconds.
    pub dt_ns: u64,
}

/// The translation of a camera's `T_BS` (its 4 x 4 `data: [...]`, over several lines), if the
/// file has one.
fn t_bs_translation(path: &Path, text: &str) -> Result<Option<[f64; 3]>, ReplayError> {
    let Some(at) = text.find("T_BS:") else {
        return Ok(None);
    };
    let block = &text[at..];
    let list = block
        .split_once('[')
        .and_then(|(_, r)| r.split_once(']'))
        .map(|(l, _)| l)
        .ok_or_else(|| {
            ReplayError::Mismatch(format!("{}: T_BS: a data: [...] list", path.display()))
        })?;
    let v: Vec<f64> = list
        .split(',')
        .map(|f| f.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| ReplayError::Mismatch(format!("{}: T_BS: 16 numbers", path.display())))?;
    if v.len() != 16 {
        return Err(ReplayError::Mismatch(format!(
            "{}: T_BS: 16 numbers, found {}",
            path.display(),
            v.len()
        )));
    }
    Ok(Some([v[3], v[7], v[11]]))
}

enum Item {
    Truth(hetsim_msgs::Pose),
    /// `cam0/data.csv`'s row, the left and the right image.
    Pair(usize, PathBuf, PathBuf),
}

/// A EuRoC dataset, open for replay.
pub struct EurocRecording {
    spec: BenchSpec,
    /// `cam0/data.csv`, named with its row when an image of a pair is bad.
    cam0: PathBuf,
    items: VecDeque<(u64, u64, Item)>,
    pending: VecDeque<Logged>,
}

fn row_error(path: &Path, row: usize, what: impl Into<String>) -> ReplayError {
    ReplayError::Row {
        path: path.to_path_buf(),
        row,
        what: what.into(),
    }
}

/// The rows of a EuRoC CSV (header skipped): row number (1-based, header = 1) and fields.
fn rows(path: &Path) -> Result<Vec<(usize, Vec<String>)>, ReplayError> {
    let text = std::fs::read_to_string(path).map_err(|e| ReplayError::file(path, e))?;
    Ok(text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty() && !l.starts_with('#'))
        .map(|(i, l)| (i + 1, l.split(',').map(|f| f.trim().to_string()).collect()))
        .collect())
}

fn stamp(path: &Path, row: usize, field: &str) -> Result<u64, ReplayError> {
    field.parse::<u64>().map_err(|_| {
        row_error(
            path,
            row,
            format!("timestamp \"{field}\": a whole number of nanoseconds"),
        )
    })
}

/// `key: [a, b, ...]` of a `sensor.yaml`, as numbers.
fn yaml_list(path: &Path, text: &str, key: &str) -> Result<Vec<f64>, ReplayError> {
    let (row, line) = text
        .lines()
        .enumerate()
        .find(|(_, l)| l.trim_start().starts_with(&format!("{key}:")))
        .ok_or_else(|| ReplayError::Mismatch(format!("{}: no \"{key}\" field", path.display())))?;
    let list = line
        .split_once('[')
        .and_then(|(_, r)| r.split_once(']'))
        .map(|(l, _)| l)
        .ok_or_else(|| row_error(path, row + 1, format!("{key}: a list [a, b, ...]")))?;
    list.split(',')
        .filter(|f| !f.trim().is_empty())
        .map(|f| {
            f.trim().parse::<f64>().map_err(|_| {
                row_error(
                    path,
                    row + 1,
                    format!("{key}: \"{}\" is not a number", f.trim()),
                )
            })
        })
        .collect()
}

/// Checks a camera's `sensor.yaml` against the bench.
fn check_camera(dir: &Path, spec: &BenchSpec) -> Result<(), ReplayError> {
    let path = dir.join("sensor.yaml");
    let text = std::fs::read_to_string(&path).map_err(|e| ReplayError::file(&path, e))?;
    let mismatch = |field: &str, got: String, want: String| {
        ReplayError::Mismatch(format!(
            "{}: {field} {got}, but robot {}'s bench {} has {want} in its robot file; hetsim's VO assumes the robot file's camera",
            path.display(),
            spec.robot,
            spec.bench
        ))
    };
    let res = yaml_list(&path, &text, "resolution")?;
    if res != [spec.width as f64, spec.height as f64] {
        return Err(mismatch(
            "resolution",
            format!("{res:?}"),
            format!("[{}, {}]", spec.width, spec.height),
        ));
    }
    let k = yaml_list(&path, &text, "intrinsics")?;
    let close = k.len() == 4
        && k.iter()
            .zip(spec.intrinsics)
            .all(|(a, b)| (a - b).abs() <= 1e-3 * b.abs().max(1.0));
    if !close {
        return Err(mismatch(
            "intrinsics",
            format!("{k:?}"),
            format!("{:?}", spec.intrinsics),
        ));
    }
    // Absent distortion is none; a malformed list is refused.
    if text.contains("distortion_coefficients:") {
        let d = yaml_list(&path, &text, "distortion_coefficients")?;
        if d.iter().any(|c| *c != 0.0) {
            return Err(mismatch(
                "distortion_coefficients",
                format!("{d:?}"),
                "rectified images (all 0)".into(),
            ));
        }
    }
    Ok(())
}

/// A camera's rows: row number, stamp and image path, every image checked to exist.
fn camera(dir: &Path) -> Result<Vec<(usize, u64, PathBuf)>, ReplayError> {
    let csv = dir.join("data.csv");
    let mut out = Vec::new();
    for (row, fields) in rows(&csv)? {
        let [t, name] = fields.as_slice() else {
            return Err(row_error(
                &csv,
                row,
                format!("{} fields: timestamp,filename", fields.len()),
            ));
        };
        let image = dir.join("data").join(name);
        if !image.is_file() {
            return Err(row_error(
                &csv,
                row,
                format!("image {name} is missing ({})", image.display()),
            ));
        }
        out.push((row, stamp(&csv, row, t)?, image));
    }
    if out.is_empty() {
        return Err(row_error(&csv, 1, "no images listed"));
    }
    Ok(out)
}

impl EurocRecording {
    /// Opens the dataset at `mav0` for the bench `spec`.
    pub fn open(mav0: &Path, spec: BenchSpec) -> Result<Self, ReplayError> {
        if !mav0.join("cam0").is_dir() || !mav0.join("cam1").is_dir() {
            return Err(ReplayError::file(
                mav0,
                "not a EuRoC dataset folder: it needs cam0/ and cam1/ (give the mav0 folder)",
            ));
        }
        for cam in ["cam0", "cam1"] {
            check_camera(&mav0.join(cam), &spec)?;
        }
        // The two cameras' distance (their T_BS translations) must be the bench's baseline:
        // the VO's scale comes from it.
        let t = |cam: &str| -> Result<Option<[f64; 3]>, ReplayError> {
            let path = mav0.join(cam).join("sensor.yaml");
            let text = std::fs::read_to_string(&path).map_err(|e| ReplayError::file(&path, e))?;
            t_bs_translation(&path, &text)
        };
        if let (Some(a), Some(b)) = (t("cam0")?, t("cam1")?) {
            let d = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
            if (d - spec.baseline_m).abs() > 1e-3 {
                return Err(ReplayError::Mismatch(format!(
                    "{}: cam0 and cam1 are {d:.4} m apart (their T_BS), but robot {}'s bench {} has a {} m baseline in its robot file; the VO's scale comes from it",
                    mav0.display(),
                    spec.robot,
                    spec.bench,
                    spec.baseline_m
                )));
            }
        }
        let (left, right) = (camera(&mav0.join("cam0"))?, camera(&mav0.join("cam1"))?);
        let shift = if left[0].1 > 86_400_000_000_000 {
            left[0].1
        } else {
            0
        };
        let dt = spec.dt_ns;
        let on_grid = |path: &Path, row: usize, t: u64| -> Result<u64, ReplayError> {
            let rel = t.checked_sub(shift).ok_or_else(|| {
                row_error(
                    path,
                    row,
                    format!("timestamp {t} is before the first image's"),
                )
            })?;
            // The nearest tick, in whole nanoseconds that fit: a stamp near 2^64 is refused.
            rel.checked_add(dt / 2)
                .map(|r| r / dt * dt)
                .filter(|log| *log <= u64::MAX / 2)
                .ok_or_else(|| row_error(path, row, format!("timestamp {t} is out of range")))
        };
        let cam0 = mav0.join("cam0/data.csv");
        let mut items = Vec::new();
        let right_at: std::collections::BTreeMap<u64, &PathBuf> =
            right.iter().map(|(_, t, p)| (*t, p)).collect();
        // One pair per tick: two would reach the robot as one inbox with two pairs.
        let mut ticks: std::collections::BTreeMap<u64, usize> = Default::default();
        for (row, t, l) in &left {
            let r = right_at.get(t).ok_or_else(|| {
                row_error(&cam0, *row, format!("no cam1 image has its timestamp {t}"))
            })?;
            let log = on_grid(&cam0, *row, *t)?;
            if let Some(other) = ticks.insert(log, *row) {
                return Err(row_error(
                    &cam0,
                    *row,
                    format!("timestamp {t} falls on the same {dt} ns tick as row {other}'s"),
                ));
            }
            items.push((log, 1, Item::Pair(*row, l.clone(), (*r).clone())));
        }
        let truth_csv = mav0.join("state_groundtruth_estimate0/data.csv");
        if truth_csv.is_file() {
            for (row, f) in rows(&truth_csv)? {
                if f.len() < 8 {
                    return Err(row_error(
                        &truth_csv,
                        row,
                        format!("{} fields: at least timestamp, p (3), q (w x y z)", f.len()),
                    ));
                }
                let t = stamp(&truth_csv, row, &f[0])?;
                let v: Vec<f64> = f[1..8]
                    .iter()
                    .map(|x| {
                        x.parse::<f64>().map_err(|_| {
                            row_error(&truth_csv, row, format!("\"{x}\" is not a number"))
                        })
                    })
                    .collect::<Result<_, _>>()?;
                if t < shift {
                    continue;
                }
                let q = nalgebra::Quaternion::new(v[3], v[4], v[5], v[6]);
                if v.iter().any(|x| !x.is_finite()) || (q.norm() - 1.0).abs() > 1e-3 {
                    return Err(row_error(
                        &truth_csv,
                        row,
                        "a finite position and a unit quaternion (w x y z) expected",
                    ));
                }
                let q = nalgebra::UnitQuaternion::from_quaternion(q);
                let pose = nalgebra::Isometry3::from_parts(
                    nalgebra::Translation3::new(v[0], v[1], v[2]),
                    q,
                );
                items.push((on_grid(&truth_csv, row, t)?, 0, Item::Truth(pose)));
            }
        }
        // Truth before images at the same tick, as a live run delivers them.
        items.sort_by_key(|(log, order, _)| (*log, *order));
        Ok(Self {
            spec,
            cam0,
            items: items
                .into_iter()
                .map(|(log, _, item)| (log, log, item))
                .collect(),
            pending: VecDeque::new(),
        })
    }

    /// Delivery time of the last image, nanoseconds.
    pub fn last_image_ns(&self) -> u64 {
        self.items
            .iter()
            .filter(|(_, _, item)| matches!(item, Item::Pair(..)))
            .map(|(log, ..)| *log)
            .max()
            .unwrap_or(0)
    }

    /// The image of a pair (row `row` of `cam0/data.csv`), decoded and checked against the
    /// bench's size.
    fn image(
        &self,
        row: usize,
        path: &Path,
        stamp_ns: u64,
        eye: &str,
    ) -> Result<SensorMsg, ReplayError> {
        let at = |what: String| {
            row_error(
                &self.cam0,
                row,
                format!("{eye} image {}: {what}", path.display()),
            )
        };
        let img = image::open(path).map_err(|e| at(e.to_string()))?;
        let (w, h) = (self.spec.width, self.spec.height);
        if (img.width(), img.height()) != (w, h) {
            return Err(at(format!(
                "{} x {} pixels, the bench's {w} x {h} expected",
                img.width(),
                img.height()
            )));
        }
        let (encoding, data) = match img {
            image::DynamicImage::ImageLuma8(g) => (PixelEncoding::Mono8, g.into_raw()),
            image::DynamicImage::ImageRgb8(c) => (PixelEncoding::Rgb8, c.into_raw()),
            other => (PixelEncoding::Mono8, other.to_luma8().into_raw()),
        };
        Ok(SensorMsg::Image(Image {
            stamp_ns,
            sensor: format!("{}/{eye}", self.spec.bench),
            width: w,
            height: h,
            encoding,
            data,
        }))
    }
}

impl Recording for EurocRecording {
    fn next_logged(&mut self) -> Result<Option<Logged>, ReplayError> {
        if let Some(l) = self.pending.pop_front() {
            return Ok(Some(l));
        }
        let Some((log_ns, stamp_ns, item)) = self.items.pop_front() else {
            return Ok(None);
        };
        let robot = self.spec.robot.clone();
        let event = match item {
            Item::Truth(pose) => Event::Truth {
                robot,
                stamp_ns,
                pose,
            },
            Item::Pair(row, left, right) => {
                let topic = |eye: &str| format!("{}/{}/{eye}", self.spec.robot, self.spec.bench);
                let right = self.image(row, &right, stamp_ns, "right")?;
                self.pending.push_back(Logged {
                    log_ns,
                    event: Event::Sensor {
                        robot: robot.clone(),
                        topic: topic("right"),
                        msg: right,
                    },
                });
                Event::Sensor {
                    robot,
                    topic: topic("left"),
                    msg: self.image(row, &left, stamp_ns, "left")?,
                }
            }
        };
        Ok(Some(Logged { log_ns, event }))
    }

    fn outcome(&self) -> Option<&[RecordedOutcome]> {
        None
    }
}
