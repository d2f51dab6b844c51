//! The net on rten's ops-as-functions API (`rten::ops::{conv, resize, concat,
//! matmul, add}`; rten's `ops` module says these "may be removed from the public API").
//! rten exports no activation functions: ReLU6 is a plain clamp loop and
//! GELU uses rten-vecmath's vectorised `Gelu` (both parallel over chunks in
//! rten's thread pool). Adaptive average pooling: none in rten, so two
//! matrix products with PyTorch's window matrices.

use rayon::prelude::*;
use rten::ops::{self, CoordTransformMode, NearestMode, Padding, ResizeMode, ResizeTarget};
use rten::BufferPool;
use rten_simd::SimdUnaryOp;
use rten_tensor::prelude::*;
use rten_tensor::{NdTensor, Tensor};

use common::{Act, Net, PSP_DIVISORS, TAP_LAYERS};

const CHUNK: usize = 16 * 1024;

struct Conv {
    w: Tensor<f32>,
    b: NdTensor<f32, 1>,
    stride: usize,
    pad: usize,
    groups: usize,
    act: Act,
    kind: &'static str,
}

impl Conv {
    fn new(c: &common::Conv) -> Self {
        Self {
            w: Tensor::from_data(&c.shape, c.w.clone()),
            b: NdTensor::from_data([c.b.len()], c.b.clone()),
            stride: c.stride,
            pad: c.pad,
            groups: c.groups,
            act: c.act,
            kind: common::conv_kind(c),
        }
    }

    fn forward(&self, pool: &BufferPool, x: &Tensor<f32>) -> Tensor<f32> {
        let p = self.pad;
        let mut y: Tensor<f32> = common::prof(self.kind, || ops::conv(
            pool,
            x.view(),
            self.w.view(),
            Some(self.b.view()),
            Padding::from([p, p, p, p]),
            self.groups,
            &[self.stride, self.stride],
            &[1, 1],
        )
        .expect("conv"));
        let data = y.data_mut().expect("contiguous");
        match self.act {
            Act::None => {}
            Act::Relu6 => common::prof("relu6", || data
                .par_chunks_mut(CHUNK)
                .for_each(|c| c.iter_mut().for_each(|v| *v = v.clamp(0.0, 6.0)))),
            Act::Gelu => common::prof("gelu", || data
                .par_chunks_mut(CHUNK)
                .for_each(|c| rten_vecmath::Gelu {}.map_mut(c))),
        }
        y
    }
}

struct Block {
    expand: Option<Conv>,
    dw: Conv,
    project: Conv,
    residual: bool,
}

pub struct Model {
    stem: Conv,
    blocks: Vec<Block>,
    last: Conv,
    psp: Vec<Conv>,
    fuse: Conv,
    steps: Vec<(Conv, Conv)>,
    head: Conv,
}

fn resize(pool: &BufferPool, x: &Tensor<f32>, h: usize, w: usize) -> Tensor<f32> {
    let s = x.shape();
    let sizes = NdTensor::from([s[0] as i32, s[1] as i32, h as i32, w as i32]);
    common::prof("resize", || ops::resize(
        pool,
        x.view(),
        ResizeTarget::Sizes(sizes.view()),
        ResizeMode::Linear,
        CoordTransformMode::PytorchHalfPixel,
        NearestMode::default(),
    )
    .expect("resize"))
}

fn add(pool: &BufferPool, a: &Tensor<f32>, b: &Tensor<f32>) -> Tensor<f32> {
    common::prof("add", || ops::add(pool, a.view(), b.view()).expect("add"))
}

fn adaptive_pool(pool: &BufferPool, x: &Tensor<f32>, oh: usize, ow: usize) -> Tensor<f32> {
    let s = x.shape();
    let (h, w) = (s[2], s[3]);
    let rows = Tensor::from_data(&[oh, h], common::pooling_matrix(h, oh));
    // cols^T: [w, ow]
    let cols = common::pooling_matrix(w, ow);
    let mut cols_t = vec![0f32; w * ow];
    for i in 0..ow {
        for j in 0..w {
            cols_t[j * ow + i] = cols[i * w + j];
        }
    }
    let cols_t = Tensor::from_data(&[w, ow], cols_t);
    let y: Tensor<f32> = ops::matmul(pool, rows.view(), x.view(), None).expect("matmul");
    ops::matmul(pool, y.view(), cols_t.view(), None).expect("matmul")
}

impl Model {
    pub fn new(n: &Net) -> Self {
        Self {
            stem: Conv::new(&n.stem),
            blocks: n
                .blocks
                .iter()
                .map(|b| Block {
                    expand: b.expand.as_ref().map(Conv::new),
                    dw: Conv::new(&b.dw),
                    project: Conv::new(&b.project),
                    residual: b.residual,
                })
                .collect(),
            last: Conv::new(&n.last),
            psp: n.psp_branches.iter().map(Conv::new).collect(),
            fuse: Conv::new(&n.psp_fuse),
            steps: n
                .steps
                .iter()
                .map(|s| (Conv::new(&s.conv), Conv::new(&s.skip)))
                .collect(),
            head: Conv::new(&n.head),
        }
    }

    pub fn forward(&self, x: Tensor<f32>) -> Tensor<f32> {
        rten::thread_pool().run(|| {
            let pool = BufferPool::new();
            self.forward_in(&pool, x)
        })
    }

    fn forward_in(&self, pool: &BufferPool, x: Tensor<f32>) -> Tensor<f32> {
        let mut taps = Vec::new();
        let mut x = self.stem.forward(pool, &x);
        for (i, b) in self.blocks.iter().enumerate() {
            let e;
            let h = match &b.expand {
                Some(c) => {
                    e = c.forward(pool, &x);
                    &e
                }
                None => &x,
            };
            let h = b.dw.forward(pool, h);
            let h = b.project.forward(pool, &h);
            x = if b.residual { add(pool, &x, &h) } else { h };
            if TAP_LAYERS.contains(&(i + 1)) {
                taps.push(x.clone());
            }
        }
        let s32 = self.last.forward(pool, &x);
        let (h, w) = (s32.shape()[2], s32.shape()[3]);
        let outs: Vec<Tensor<f32>> = self
            .psp
            .iter()
            .zip(PSP_DIVISORS)
            .map(|(branch, d)| {
                if d == 1 {
                    return branch.forward(pool, &s32);
                }
                let pooled = common::prof("adaptive pool", || {
                    adaptive_pool(pool, &s32, common::pooled_side(h, d), common::pooled_side(w, d))
                });
                resize(pool, &branch.forward(pool, &pooled), h, w)
            })
            .collect();
        let views: Vec<_> = outs.iter().map(|t| t.view()).collect();
        let cat = common::prof("cat", || ops::concat(pool, &views, 1).expect("concat"));
        let mut x = self.fuse.forward(pool, &cat);
        for ((conv, skip), tap) in self.steps.iter().zip([&taps[2], &taps[1], &taps[0]]) {
            let (th, tw) = (tap.shape()[2], tap.shape()[3]);
            let up = resize(pool, &conv.forward(pool, &x), th, tw);
            x = add(pool, &up, &skip.forward(pool, tap));
        }
        self.head.forward(pool, &x)
    }
}
