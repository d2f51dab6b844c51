//! Shared by the benchmark binaries: the shipped weights with BatchNorm folded
//! (in f64, eps 1e-5) into the convs, the net's topology, input/output files,
//! and the timing harness.

use std::time::Instant;

/// Activation after a conv.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Act {
    None,
    Relu6,
    Gelu,
}

/// A conv with folded BN: weight `[o, i/groups, k, k]` and bias `[o]`.
#[derive(Clone, Debug)]
pub struct Conv {
    pub w: Vec<f32>,
    pub shape: [usize; 4],
    pub b: Vec<f32>,
    pub stride: usize,
    pub pad: usize,
    pub groups: usize,
    pub act: Act,
}

/// An inverted-residual block.
#[derive(Clone, Debug)]
pub struct Block {
    pub expand: Option<Conv>,
    pub dw: Conv,
    pub project: Conv,
    pub residual: bool,
}

/// A decoder step.
#[derive(Clone, Debug)]
pub struct Step {
    pub conv: Conv,
    pub skip: Conv,
}

/// The learned part of the net.
#[derive(Clone, Debug)]
pub struct Net {
    pub stem: Conv,
    pub blocks: Vec<Block>,
    pub last: Conv,
    pub psp_branches: Vec<Conv>,
    pub psp_fuse: Conv,
    pub steps: Vec<Step>,
    pub head: Conv,
}

/// The `features` indices after which the taps at strides 4, 8, 16 are taken.
pub const TAP_LAYERS: [usize; 3] = [3, 6, 13];
/// PSP pooling divisors.
pub const PSP_DIVISORS: [usize; 4] = [1, 2, 4, 8];

/// Rust's `max(1, round(n / d))` (f64 round-half-away), as psp.rs.
pub fn pooled_side(n: usize, d: usize) -> usize {
    ((n as f64 / d as f64).round() as usize).max(1)
}

/// The `n_out x n_in` matrix of PyTorch adaptive average pooling along one
/// axis (windows floor(i n/o) .. ceil((i+1) n/o)), row-major.
pub fn pooling_matrix(n_in: usize, n_out: usize) -> Vec<f32> {
    let mut m = vec![0f32; n_out * n_in];
    for i in 0..n_out {
        let start = i * n_in / n_out;
        let end = ((i + 1) * n_in).div_ceil(n_out);
        for j in start..end {
            m[i * n_in + j] = 1.0 / (end - start) as f32;
        }
    }
    m
}

struct Tensors<'a> {
    st: safetensors::SafeTensors<'a>,
}

impl Tensors<'_> {
    fn get(&self, name: &str) -> (Vec<usize>, Vec<f64>) {
        let t = self
            .st
            .tensor(name)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        let data = t.data();
        let values: Vec<f64> = match t.dtype() {
            safetensors::Dtype::F16 => data
                .chunks_exact(2)
                .map(|c| half::f16::from_le_bytes([c[0], c[1]]).to_f64())
                .collect(),
            safetensors::Dtype::F32 => data
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]) as f64)
                .collect(),
            d => panic!("{name}: dtype {d:?}"),
        };
        (t.shape().to_vec(), values)
    }

    /// Conv weight `wname` folded with BN under `bn` (`weight`, `bias`,
    /// `running_mean`, `running_var`).
    fn conv_bn(&self, wname: &str, bn: &str, stride: usize, groups: usize, act: Act) -> Conv {
        let (shape, w) = self.get(wname);
        let (_, gamma) = self.get(&format!("{bn}.weight"));
        let (_, beta) = self.get(&format!("{bn}.bias"));
        let (_, mean) = self.get(&format!("{bn}.running_mean"));
        let (_, var) = self.get(&format!("{bn}.running_var"));
        let o = shape[0];
        let per = w.len() / o;
        let mut wf = vec![0f32; w.len()];
        let mut bf = vec![0f32; o];
        for c in 0..o {
            let s = gamma[c] / (var[c] + 1e-5).sqrt();
            for k in 0..per {
                wf[c * per + k] = (w[c * per + k] * s) as f32;
            }
            bf[c] = (beta[c] - mean[c] * s) as f32;
        }
        Conv {
            w: wf,
            shape: [shape[0], shape[1], shape[2], shape[3]],
            b: bf,
            stride,
            pad: shape[2] / 2,
            groups,
            act,
        }
    }
}

/// Loads the learned part of the shipped net.
pub fn load_net(path: &str) -> Net {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let t = Tensors {
        st: safetensors::SafeTensors::deserialize(&bytes).expect("safetensors"),
    };
    let f = |i: usize| format!("encoder.features.{i}");
    let stem = t.conv_bn(&format!("{}.0.weight", f(0)), &format!("{}.1", f(0)), 2, 1, Act::Relu6);
    const SETTINGS: [(usize, usize, usize, usize); 7] = [
        (1, 16, 1, 1),
        (6, 24, 2, 2),
        (6, 32, 3, 2),
        (6, 64, 4, 2),
        (6, 96, 3, 1),
        (6, 160, 3, 2),
        (6, 320, 1, 1),
    ];
    let mut blocks = Vec::new();
    let mut c_in = 32;
    for (e, c, n, s) in SETTINGS {
        for i in 0..n {
            let stride = if i == 0 { s } else { 1 };
            let p = format!("{}.conv", f(blocks.len() + 1));
            let hidden = c_in * e;
            let (expand, next) = if e == 1 {
                (None, 0)
            } else {
                (Some(t.conv_bn(&format!("{p}.0.0.weight"), &format!("{p}.0.1"), 1, 1, Act::Relu6)), 1)
            };
            let dw = t.conv_bn(
                &format!("{p}.{next}.0.weight"),
                &format!("{p}.{next}.1"),
                stride,
                hidden,
                Act::Relu6,
            );
            let project = t.conv_bn(
                &format!("{p}.{}.weight", next + 1),
                &format!("{p}.{}", next + 2),
                1,
                1,
                Act::None,
            );
            blocks.push(Block {
                expand,
                dw,
                project,
                residual: stride == 1 && c_in == c,
            });
            c_in = c;
        }
    }
    let last = t.conv_bn(&format!("{}.0.weight", f(18)), &format!("{}.1", f(18)), 1, 1, Act::Relu6);
    let cbg = |p: String| t.conv_bn(&format!("{p}.conv.weight"), &format!("{p}.bn"), 1, 1, Act::Gelu);
    let psp_branches = (0..4).map(|i| cbg(format!("psp.branches.{i}"))).collect();
    let psp_fuse = cbg("psp.fuse".into());
    let steps = (0..3)
        .map(|i| Step {
            conv: cbg(format!("decoder.steps.{i}.conv")),
            skip: cbg(format!("decoder.steps.{i}.skip")),
        })
        .collect();
    let (hs, hw) = t.get("head.weight");
    let (_, hb) = t.get("head.bias");
    let head = Conv {
        w: hw.iter().map(|&v| v as f32).collect(),
        shape: [hs[0], hs[1], hs[2], hs[3]],
        b: hb.iter().map(|&v| v as f32).collect(),
        stride: 1,
        pad: 0,
        groups: 1,
        act: Act::None,
    };
    Net {
        stem,
        blocks,
        last,
        psp_branches,
        psp_fuse,
        steps,
        head,
    }
}

/// Command line: `BIN <model.safetensors> <input.f32> <H> <W> <out.f32> [runs] [warmups]`.
pub struct Args {
    pub model: String,
    pub input: Vec<f32>,
    pub h: usize,
    pub w: usize,
    pub out: String,
    pub runs: usize,
    pub warmups: usize,
}

pub fn args() -> Args {
    let a: Vec<String> = std::env::args().collect();
    if a.len() < 6 {
        eprintln!("usage: {} MODEL INPUT.f32 H W OUT.f32 [runs=5] [warmups=2]", a[0]);
        std::process::exit(2);
    }
    let h: usize = a[3].parse().unwrap();
    let w: usize = a[4].parse().unwrap();
    let bytes = std::fs::read(&a[2]).unwrap();
    let input: Vec<f32> = bytes
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    assert_eq!(input.len(), 3 * h * w, "input size");
    Args {
        model: a[1].clone(),
        input,
        h,
        w,
        out: a[5].clone(),
        runs: a.get(6).map(|s| s.parse().unwrap()).unwrap_or(5),
        warmups: a.get(7).map(|s| s.parse().unwrap()).unwrap_or(2),
    }
}

/// Runs `forward` warmups + runs times, prints the timings and the median,
/// writes the last output to `out` (raw f32 LE) and returns it.
pub fn bench(label: &str, args: &Args, mut forward: impl FnMut() -> Vec<f32>) -> Vec<f32> {
    let mut times = Vec::new();
    let mut out = Vec::new();
    for i in 0..args.warmups + args.runs {
        if i == args.warmups {
            PROFILE.lock().unwrap().clear();
        }
        let t0 = Instant::now();
        out = forward();
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        eprintln!("{label} {}x{} run {i}: {ms:.1} ms{}", args.w, args.h, if i < args.warmups { " (warm-up)" } else { "" });
        if i >= args.warmups {
            times.push(ms);
        }
    }
    let mut sorted = times.clone();
    sorted.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let median = sorted[sorted.len() / 2];
    println!(
        "RESULT {label} {}x{} median_ms={median:.1} min_ms={:.1} max_ms={:.1} runs={:?}",
        args.w,
        args.h,
        sorted[0],
        sorted[sorted.len() - 1],
        times.iter().map(|t| (t * 10.0).round() / 10.0).collect::<Vec<_>>()
    );
    print_profile(args.runs, times.iter().sum());
    let bytes: Vec<u8> = out.iter().flat_map(|v| v.to_le_bytes()).collect();
    std::fs::write(&args.out, bytes).unwrap();
    out
}

// ---- optional per-op-kind profile (PROFILE=1), for eager backends ----

use std::sync::Mutex;

static PROFILE: Mutex<Vec<(&'static str, f64, usize)>> = Mutex::new(Vec::new());

pub fn profiling() -> bool {
    static ON: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *ON.get_or_init(|| std::env::var("PROFILE").is_ok())
}

/// Times `f` under `kind` when PROFILE is set.
pub fn prof<R>(kind: &'static str, f: impl FnOnce() -> R) -> R {
    if !profiling() {
        return f();
    }
    let t0 = Instant::now();
    let r = f();
    let ms = t0.elapsed().as_secs_f64() * 1e3;
    let mut p = PROFILE.lock().unwrap();
    match p.iter_mut().find(|e| e.0 == kind) {
        Some(e) => {
            e.1 += ms;
            e.2 += 1;
        }
        None => p.push((kind, ms, 1)),
    }
    r
}

/// The kind of a conv for the profile.
pub fn conv_kind(c: &Conv) -> &'static str {
    if c.groups > 1 {
        if c.stride == 2 { "conv dw 3x3 s2" } else { "conv dw 3x3 s1" }
    } else if c.shape[2] == 1 {
        "conv 1x1"
    } else {
        "conv 3x3 dense"
    }
}

/// Prints and clears the profile (per forward: divided by `forwards`).
pub fn print_profile(forwards: usize, total_ms: f64) {
    if !profiling() {
        return;
    }
    let mut p = PROFILE.lock().unwrap();
    let mut sum = 0.0;
    for (k, ms, n) in p.iter() {
        eprintln!("PROFILE {k:<16} {:8.1} ms/forward ({} calls/forward)", ms / forwards as f64, n / forwards);
        sum += ms;
    }
    eprintln!("PROFILE {:<16} {:8.1} ms/forward", "rest", (total_ms - sum) / forwards as f64);
    p.clear();
}
