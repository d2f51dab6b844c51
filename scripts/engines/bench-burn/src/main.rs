//! burn 0.22.1, flex backend: MobileNetV2 + PSP + decoder + head.

use burn::tensor::activation::gelu;
use burn::tensor::module::{adaptive_avg_pool2d, conv2d, interpolate};
use burn::tensor::ops::{ConvOptions, InterpolateMode, InterpolateOptions};
use burn::tensor::{Device, Tensor, TensorData};
use common::{Act, Net, PSP_DIVISORS, TAP_LAYERS};

struct Conv {
    w: Tensor<4>,
    b: Tensor<1>,
    opts: ConvOptions<2>,
    act: Act,
    kind: &'static str,
}

impl Conv {
    fn new(c: &common::Conv, dev: &Device) -> Self {
        Self {
            w: Tensor::from_data(TensorData::new(c.w.clone(), c.shape), dev),
            b: Tensor::from_data(TensorData::new(c.b.clone(), [c.b.len()]), dev),
            opts: ConvOptions::new([c.stride; 2], [c.pad; 2], [1, 1], c.groups),
            act: c.act,
            kind: common::conv_kind(c),
        }
    }

    fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let y = common::prof(self.kind, || {
            conv2d(x, self.w.clone(), Some(self.b.clone()), self.opts.clone())
        });
        match self.act {
            Act::None => y,
            Act::Relu6 => common::prof("relu6", || y.clamp(0.0, 6.0)),
            Act::Gelu => common::prof("gelu", || gelu(y)),
        }
    }
}

struct Block {
    expand: Option<Conv>,
    dw: Conv,
    project: Conv,
    residual: bool,
}

struct Model {
    stem: Conv,
    blocks: Vec<Block>,
    last: Conv,
    psp: Vec<Conv>,
    fuse: Conv,
    steps: Vec<(Conv, Conv)>,
    head: Conv,
}

fn resize(x: Tensor<4>, h: usize, w: usize) -> Tensor<4> {
    common::prof("resize", || interpolate(
        x,
        InterpolateOptions::new(InterpolateMode::Bilinear)
            .with_align_corners(false)
            .with_output_size([h, w]),
    ))
}

impl Model {
    fn new(n: &Net, dev: &Device) -> Self {
        Self {
            stem: Conv::new(&n.stem, dev),
            blocks: n
                .blocks
                .iter()
                .map(|b| Block {
                    expand: b.expand.as_ref().map(|c| Conv::new(c, dev)),
                    dw: Conv::new(&b.dw, dev),
                    project: Conv::new(&b.project, dev),
                    residual: b.residual,
                })
                .collect(),
            last: Conv::new(&n.last, dev),
            psp: n.psp_branches.iter().map(|c| Conv::new(c, dev)).collect(),
            fuse: Conv::new(&n.psp_fuse, dev),
            steps: n
                .steps
                .iter()
                .map(|s| (Conv::new(&s.conv, dev), Conv::new(&s.skip, dev)))
                .collect(),
            head: Conv::new(&n.head, dev),
        }
    }

    fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let mut taps = Vec::new();
        let mut x = self.stem.forward(x);
        for (i, b) in self.blocks.iter().enumerate() {
            let mut h = match &b.expand {
                Some(e) => e.forward(x.clone()),
                None => x.clone(),
            };
            h = b.dw.forward(h);
            h = b.project.forward(h);
            x = if b.residual { common::prof("add", || x + h) } else { h };
            if TAP_LAYERS.contains(&(i + 1)) {
                taps.push(x.clone());
            }
        }
        let s32 = self.last.forward(x);
        // PSP
        let [_, _, h, w] = s32.dims();
        let outs: Vec<Tensor<4>> = self
            .psp
            .iter()
            .zip(PSP_DIVISORS)
            .map(|(branch, d)| {
                if d == 1 {
                    return branch.forward(s32.clone());
                }
                let (ph, pw) = (common::pooled_side(h, d), common::pooled_side(w, d));
                let pooled = common::prof("adaptive pool", || adaptive_avg_pool2d(s32.clone(), [ph, pw]));
                resize(branch.forward(pooled), h, w)
            })
            .collect();
        let mut x = self.fuse.forward(common::prof("cat", || Tensor::cat(outs, 1)));
        // decoder
        for ((conv, skip), tap) in self.steps.iter().zip([&taps[2], &taps[1], &taps[0]]) {
            let [_, _, th, tw] = tap.dims();
            let up = resize(conv.forward(x), th, tw);
            let sk = skip.forward(tap.clone());
            x = common::prof("add", || up + sk);
        }
        self.head.forward(x)
    }
}

fn main() {
    let args = common::args();
    let dev = Device::flex();
    let net = common::load_net(&args.model);
    let model = Model::new(&net, &dev);
    drop(net);
    common::bench("burn-flex", &args, || {
        let x: Tensor<4> =
            Tensor::from_data(TensorData::new(args.input.clone(), [1, 3, args.h, args.w]), &dev);
        let y = model.forward(x);
        common::prof("to_vec", || y.into_data().into_vec::<f32>().unwrap())
    });
}
