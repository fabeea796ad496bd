//! `hetsim sweep SWEEP.toml --slurm`: a sweep as a Slurm job array, one array task per
//! shard, and a merge job that runs once every task has succeeded (`afterok`).
//!
//! Writes, under `OUT/slurm/`: `array.sbatch` (task `k` of `N` runs
//! `hetsim sweep SWEEP --shard k/N --out OUT/shards/k`), `merge.sbatch`
//! (`hetsim sweep merge SWEEP OUT/shards/1 .. OUT/shards/N --out OUT`), `submit.sh` (submits
//! both, the merge job depending on the array), and `logs/` for the jobs' output. Paths in
//! the scripts are absolute, so they run from any folder of a cluster whose nodes share the
//! file system. The merged folder is the one `hetsim sweep SWEEP --out OUT` writes on one
//! machine: shards own disjoint runs, each run is a pure function of its inputs, and the
//! summary is rebuilt from the rows in run order.

use anyhow::{Context, Result};
use hetsim_eval::sweep::Sweep;
use std::path::{Path, PathBuf};

/// How the job array is laid out.
pub struct SlurmOptions {
    /// Array tasks (shards).
    pub shards: usize,
    /// CPUs per task (`--cpus-per-task`; the task runs that many runs at once).
    pub cpus: usize,
    /// Extra `#SBATCH` options, e.g. `--partition=long`.
    pub extra: Vec<String>,
}

/// The scripts written.
pub struct SlurmScripts {
    /// The job array.
    pub array: PathBuf,
    /// The merge job.
    pub merge: PathBuf,
    /// Submits both.
    pub submit: PathBuf,
}

/// A shell word in single quotes.
fn quote(s: &str) -> String {
    format!("'{}'", s.replace('\'', r"'\''"))
}

fn absolute(p: &Path) -> Result<PathBuf> {
    Ok(if p.is_absolute() {
        p.to_path_buf()
    } else {
        std::env::current_dir()
            .context("the current folder")?
            .join(p)
    })
}

/// Writes the scripts for `sweep` with results in `out`.
pub fn write_scripts(sweep: &Sweep, out: &Path, options: &SlurmOptions) -> Result<SlurmScripts> {
    anyhow::ensure!(
        (1..=10_000).contains(&options.shards),
        "--shards {}: expected 1 to 10000 array tasks",
        options.shards
    );
    anyhow::ensure!(
        (1..=1024).contains(&options.cpus),
        "--jobs {}: expected 1 to 1024 CPUs per array task",
        options.cpus
    );
    for opt in &options.extra {
        anyhow::ensure!(
            opt.starts_with('-') && !opt.contains('\n'),
            "--sbatch {opt:?}: expected one sbatch option on one line, e.g. --partition=long"
        );
    }
    let out = absolute(out)?;
    let bin = std::env::current_exe().context("finding the hetsim binary")?;
    let cwd = std::env::current_dir().context("the current folder")?;
    let dir = out.join("slurm");
    let logs = dir.join("logs");
    std::fs::create_dir_all(&logs).with_context(|| format!("creating {}", logs.display()))?;
    let (n, name) = (options.shards, &sweep.file.name);
    let q = |p: &Path| quote(&p.display().to_string());
    let extra: String = options
        .extra
        .iter()
        .map(|o| format!("#SBATCH {o}\n"))
        .collect();
    let array = format!(
        "#!/bin/bash\n\
         # hetsim sweep {name}: {runs} runs in {n} array tasks; written by `hetsim sweep --slurm`.\n\
         #SBATCH --job-name=hetsim-{name}\n\
         #SBATCH --array=1-{n}\n\
         #SBATCH --ntasks=1\n\
         #SBATCH --cpus-per-task={cpus}\n\
         #SBATCH --chdir={cwd}\n\
         #SBATCH --output={logs}/shard-%a.out\n\
         {extra}\
         set -euo pipefail\n\
         exec {bin} sweep {sweep} --shard \"${{SLURM_ARRAY_TASK_ID}}/{n}\" --jobs \"${{SLURM_CPUS_PER_TASK:-{cpus}}}\" --out {out}/shards/\"${{SLURM_ARRAY_TASK_ID}}\"\n",
        runs = sweep.runs.len(),
        cpus = options.cpus,
        cwd = cwd.display(),
        logs = logs.display(),
        bin = q(&bin),
        sweep = q(&sweep.path),
        out = q(&out),
    );
    let shards: Vec<String> = (1..=n)
        .map(|k| q(&out.join("shards").join(k.to_string())))
        .collect();
    let merge = format!(
        "#!/bin/bash\n\
         # Joins the {n} shards of hetsim sweep {name} once every array task succeeded.\n\
         #SBATCH --job-name=hetsim-{name}-merge\n\
         #SBATCH --ntasks=1\n\
         #SBATCH --cpus-per-task=1\n\
         #SBATCH --chdir={cwd}\n\
         #SBATCH --output={logs}/merge-%j.out\n\
         {extra}\
         set -euo pipefail\n\
         exec {bin} sweep merge {sweep} {shards} --out {out}\n",
        cwd = cwd.display(),
        logs = logs.display(),
        bin = q(&bin),
        sweep = q(&sweep.path),
        shards = shards.join(" "),
        out = q(&out),
    );
    let paths = SlurmScripts {
        array: dir.join("array.sbatch"),
        merge: dir.join("merge.sbatch"),
        submit: dir.join("submit.sh"),
    };
    let submit = format!(
        "#!/bin/bash\n\
         # Submits hetsim sweep {name}: the job array, then the merge job after it (afterok).\n\
         set -euo pipefail\n\
         array=$(sbatch --parsable {array})\n\
         array=${{array%%;*}}\n\
         merge=$(sbatch --parsable --dependency=afterok:\"$array\" {merge})\n\
         echo \"array job $array, merge job ${{merge%%;*}}; results: {out}\"\n",
        array = q(&paths.array),
        merge = q(&paths.merge),
        out = out.display(),
    );
    for (path, text) in [
        (&paths.array, &array),
        (&paths.merge, &merge),
        (&paths.submit, &submit),
    ] {
        hetsim_core::files::write_atomic(path, text.as_bytes())?;
    }
    Ok(paths)
}

/// Submits the scripts: the array, then the merge job depending on it. Returns both job ids.
pub fn submit(scripts: &SlurmScripts) -> Result<(String, String)> {
    let sbatch = |args: &[&str]| -> Result<String> {
        let output = std::process::Command::new("sbatch")
            .arg("--parsable")
            .args(args)
            .output()
            .context("running sbatch (is Slurm installed, and SLURM_CONF set where needed?)")?;
        anyhow::ensure!(
            output.status.success(),
            "sbatch {}: {}",
            args.join(" "),
            String::from_utf8_lossy(&output.stderr).trim()
        );
        let id = String::from_utf8_lossy(&output.stdout).trim().to_string();
        // --parsable prints `id` or `id;cluster`.
        Ok(id.split(';').next().unwrap_or_default().to_string())
    };
    let array = sbatch(&[&scripts.array.display().to_string()])?;
    let merge = sbatch(&[
        &format!("--dependency=afterok:{array}"),
        &scripts.merge.display().to_string(),
    ])?;
    Ok((array, merge))
}
