//! The cluster files in deploy/: the SLURM array job and the Kubernetes
//! Indexed Job run `matseg generate` unchanged, one job per index; every
//! shard is written by exactly one job, and the jobs' output together is
//! byte-identical to one process's, whether the jobs run one after the
//! other or at once. `submit.sh` sets the array from the
//! job count and refuses more jobs than shards.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

const MATSEG: &str = env!("CARGO_BIN_EXE_matseg");
/// Small scenes, so the dataset is quick to make.
const SIZE_RANGE: [&str; 2] = ["--size-range", "64..128"];

fn deploy(file: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../deploy")
        .join(file)
}

/// A command without the job-index variables of the environment it runs in.
fn clean(program: impl AsRef<std::ffi::OsStr>) -> Command {
    let mut command = Command::new(program);
    command
        .env_remove("SLURM_ARRAY_TASK_ID")
        .env_remove("JOB_COMPLETION_INDEX");
    command
}

/// Every file under `dir` (names relative to it) and its bytes.
fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .map(|p| {
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            (name, std::fs::read(&p).unwrap())
        })
        .collect()
}

/// One process's dataset of `samples` in shards of `shard_size`.
fn one_process(out: &Path, samples: u64, shard_size: u64) -> BTreeMap<String, Vec<u8>> {
    let status = clean(MATSEG)
        .args(["generate", "--format", "wds", "--threads", "1"])
        .args(SIZE_RANGE)
        .arg("--out")
        .arg(out)
        .args([
            "--samples",
            &samples.to_string(),
            "--shard-size",
            &shard_size.to_string(),
        ])
        .status()
        .unwrap();
    assert!(status.success());
    files(out)
}

/// The shard files `job` of `jobs` owns among `shards`.
fn shards_of(job: u64, jobs: u64, shards: u64) -> Vec<String> {
    (0..shards)
        .filter(|s| s % jobs == job)
        .map(|s| {
            let path = matseg_data::wds::shard_path(Path::new(""), s);
            path.display().to_string()
        })
        .collect()
}

#[test]
fn slurm_array_jobs_write_each_shard_once_and_match_one_process() {
    let (samples, shard_size, jobs) = (10, 2, 3);
    // Job `job` of the array, writing into `out`.
    let array_job = |job: u64, out: &Path| {
        let mut command = clean("bash");
        command
            .arg(deploy("slurm/generate.sbatch"))
            .env("SLURM_ARRAY_TASK_ID", job.to_string())
            .env("SLURM_CPUS_PER_TASK", "1")
            .env("MATSEG", MATSEG)
            .env("OUT", out)
            .env("SAMPLES", samples.to_string())
            .env("SHARD_SIZE", shard_size.to_string())
            .env("JOBS", jobs.to_string())
            .env("MATSEG_ARGS", SIZE_RANGE.join(" "));
        command
    };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("array");
    let mut seen: Vec<String> = Vec::new();
    for job in 0..jobs {
        let run = array_job(job, &out).output().unwrap();
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        let now: Vec<String> = files(&out)
            .into_keys()
            .filter(|name| name.ends_with(".tar") && !seen.contains(name))
            .collect();
        assert_eq!(
            now,
            shards_of(job, jobs, 5),
            "job {job} writes its own shards"
        );
        seen.extend(now);
    }
    assert_eq!(seen.len(), 5, "every shard once");
    let single = one_process(&dir.path().join("single"), samples, shard_size);
    assert_eq!(
        files(&out),
        single,
        "the array's dataset is one process's, byte for byte"
    );

    // The jobs at once, as an array runs them, into one folder.
    let together = dir.path().join("together");
    let running: Vec<_> = (0..jobs)
        .map(|job| array_job(job, &together).spawn().unwrap())
        .collect();
    for mut job in running {
        assert!(job.wait().unwrap().success());
    }
    assert_eq!(
        files(&together),
        single,
        "concurrent jobs, the same dataset"
    );

    // Outside an array the job refuses to run rather than act as job 0.
    let outside = clean("bash")
        .arg(deploy("slurm/generate.sbatch"))
        .env("MATSEG", MATSEG)
        .output()
        .unwrap();
    assert!(!outside.status.success());
    assert!(String::from_utf8_lossy(&outside.stderr).contains("run this as a SLURM array job"));
}

#[test]
fn submit_sets_the_array_to_the_job_count_and_refuses_more_jobs_than_shards() {
    let dir = tempfile::tempdir().unwrap();
    // A stand-in sbatch that records its arguments and the settings.
    let sbatch = dir.path().join("sbatch");
    let record = dir.path().join("submitted");
    std::fs::write(
        &sbatch,
        format!(
            "#!/bin/sh\necho \"$@ JOBS=$JOBS SAMPLES=$SAMPLES\" > {}\n",
            record.display()
        ),
    )
    .unwrap();
    Command::new("chmod")
        .arg("+x")
        .arg(&sbatch)
        .status()
        .unwrap();
    let path = format!(
        "{}:{}",
        dir.path().display(),
        std::env::var("PATH").unwrap()
    );
    let submit = |jobs: u32| {
        clean("bash")
            .arg(deploy("slurm/submit.sh"))
            .arg("--partition=cpu")
            .env("PATH", &path)
            .env("MATSEG", MATSEG)
            .env("OUT", dir.path().join("data"))
            .env("SAMPLES", "10")
            .env("SHARD_SIZE", "2")
            .env("JOBS", jobs.to_string())
            .env("MAX_RUNNING", "2")
            .output()
            .unwrap()
    };
    let ok = submit(3);
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    let submitted = std::fs::read_to_string(&record).unwrap();
    let want = format!(
        "--array=0-2%2 --export=ALL --partition=cpu {} JOBS=3 SAMPLES=10\n",
        deploy("slurm/generate.sbatch")
            .canonicalize()
            .unwrap()
            .display()
    );
    assert_eq!(submitted, want);
    let too_many = submit(6);
    assert_eq!(too_many.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&too_many.stderr)
        .contains("the dataset has 5 shards of 2 samples: give 1 to 5 jobs"));
}

#[test]
fn the_kubernetes_indexed_job_has_one_index_per_shard_job_and_matches_one_process() {
    let manifest = std::fs::read_to_string(deploy("kubernetes/generate-job.yaml")).unwrap();
    let value = |key: &str| -> String {
        let line = manifest
            .lines()
            .find(|l| l.trim_start().starts_with(&format!("{key}:")))
            .unwrap_or_else(|| panic!("no {key}"));
        line.split_once(':').unwrap().1.trim().to_string()
    };
    assert_eq!(value("completionMode"), "Indexed");
    let command: Vec<String> = serde_json::from_str(&value("command")).unwrap();
    let flag = |name: &str| command[command.iter().position(|a| a == name).unwrap() + 1].clone();
    assert_eq!(
        value("completions"),
        flag("--num-shards"),
        "one index per job"
    );
    assert_eq!(flag("--format"), "wds");

    // The pods' command, at a small size, with the index Kubernetes gives.
    let (samples, shard_size, jobs) = (10u64, 2u64, 3u64);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("indexed");
    for job in 0..jobs {
        let mut args = command[1..].to_vec();
        let mut set = |name: &str, value: String| {
            let at = args.iter().position(|a| a == name).unwrap() + 1;
            args[at] = value;
        };
        set("--out", out.display().to_string());
        set("--samples", samples.to_string());
        set("--shard-size", shard_size.to_string());
        set("--num-shards", jobs.to_string());
        set("--threads", "1".into());
        let status = clean(MATSEG)
            .args(&args)
            .args(SIZE_RANGE)
            .env("JOB_COMPLETION_INDEX", job.to_string())
            .status()
            .unwrap();
        assert!(status.success());
    }
    let single = one_process(&dir.path().join("single"), samples, shard_size);
    assert_eq!(files(&out), single);
}
