//! candle-core 0.11.1 (CPU): MobileNetV2 + PSP + decoder + head.
//!
//! candle has no adaptive average pooling: it is done as two matrix products
//! with PyTorch's window matrices (as python/matseg/net.py does for ONNX).
//! Depthwise convs: `CANDLE_DW=conv` (default) uses candle's grouped conv2d
//! (one conv per channel); `CANDLE_DW=shift` computes them from 9 shifted
//! views times per-channel weights (only tensor ops, no custom kernel).

use candle_core::{Device, Result, Tensor};
use common::{Act, Net, PSP_DIVISORS, TAP_LAYERS};

struct Conv {
    w: Tensor,
    b: Tensor,
    /// For depthwise convs in shift mode: the 9 taps `[1, C, 1, 1]`.
    taps: Option<Vec<Tensor>>,
    stride: usize,
    pad: usize,
    groups: usize,
    act: Act,
    kind: &'static str,
}

impl Conv {
    fn new(c: &common::Conv, dev: &Device, shift: bool) -> Result<Self> {
        let depthwise = c.groups > 1 && c.groups == c.shape[0] && c.shape[1] == 1;
        let taps = if shift && depthwise {
            let ch = c.shape[0];
            Some(
                (0..9)
                    .map(|k| {
                        let v: Vec<f32> = (0..ch).map(|o| c.w[o * 9 + k]).collect();
                        Tensor::from_vec(v, (1, ch, 1, 1), dev)
                    })
                    .collect::<Result<Vec<_>>>()?,
            )
        } else {
            None
        };
        Ok(Self {
            w: Tensor::from_vec(c.w.clone(), &c.shape, dev)?,
            b: Tensor::from_vec(c.b.clone(), (1, c.b.len(), 1, 1), dev)?,
            taps,
            stride: c.stride,
            pad: c.pad,
            groups: c.groups,
            act: c.act,
            kind: common::conv_kind(c),
        })
    }

    /// Depthwise 3x3, padding 1, stride 1 or 2 (even sides) from shifted views.
    fn depthwise_shift(&self, x: &Tensor, taps: &[Tensor]) -> Result<Tensor> {
        let (n, c, h, w) = x.dims4()?;
        let xp = x.pad_with_zeros(2, 1, 1)?.pad_with_zeros(3, 1, 1)?;
        let mut acc: Option<Tensor> = None;
        if self.stride == 1 {
            for ky in 0..3 {
                for kx in 0..3 {
                    let patch = xp.narrow(2, ky, h)?.narrow(3, kx, w)?;
                    let term = patch.broadcast_mul(&taps[ky * 3 + kx])?;
                    acc = Some(match acc {
                        None => term,
                        Some(a) => (a + term)?,
                    });
                }
            }
            Ok(acc.unwrap())
        } else {
            assert!(self.stride == 2 && h % 2 == 0 && w % 2 == 0);
            let (oh, ow) = (h / 2, w / 2);
            // rows 2a + p, columns 2b + q of the padded input
            let x6 = xp.reshape((n, c, oh + 1, 2, ow + 1, 2))?;
            let t6: Vec<Tensor> = taps
                .iter()
                .map(|t| t.reshape((1, c, 1, 1, 1, 1)))
                .collect::<Result<_>>()?;
            for ky in 0..3 {
                for kx in 0..3 {
                    let patch = x6
                        .narrow(2, ky / 2, oh)?
                        .narrow(3, ky % 2, 1)?
                        .narrow(4, kx / 2, ow)?
                        .narrow(5, kx % 2, 1)?;
                    let term = patch.broadcast_mul(&t6[ky * 3 + kx])?;
                    acc = Some(match acc {
                        None => term,
                        Some(a) => (a + term)?,
                    });
                }
            }
            acc.unwrap().reshape((n, c, oh, ow))
        }
    }

    fn forward(&self, x: &Tensor) -> Result<Tensor> {
        let y = common::prof(self.kind, || match &self.taps {
            Some(taps) => self.depthwise_shift(x, taps),
            None => x.conv2d(&self.w, self.pad, self.stride, 1, self.groups),
        })?;
        let y = common::prof("bias", || y.broadcast_add(&self.b))?;
        match self.act {
            Act::None => Ok(y),
            Act::Relu6 => common::prof("relu6", || y.clamp(0f32, 6f32)),
            Act::Gelu => common::prof("gelu", || y.gelu_erf()),
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
    dev: Device,
}

impl Model {
    fn new(n: &Net, dev: &Device, shift: bool) -> Result<Self> {
        let c = |c: &common::Conv| Conv::new(c, dev, shift);
        Ok(Self {
            stem: c(&n.stem)?,
            blocks: n
                .blocks
                .iter()
                .map(|b| {
                    Ok(Block {
                        expand: b.expand.as_ref().map(c).transpose()?,
                        dw: c(&b.dw)?,
                        project: c(&b.project)?,
                        residual: b.residual,
                    })
                })
                .collect::<Result<_>>()?,
            last: c(&n.last)?,
            psp: n.psp_branches.iter().map(c).collect::<Result<_>>()?,
            fuse: c(&n.psp_fuse)?,
            steps: n
                .steps
                .iter()
                .map(|s| Ok((c(&s.conv)?, c(&s.skip)?)))
                .collect::<Result<_>>()?,
            head: c(&n.head)?,
            dev: dev.clone(),
        })
    }

    /// Adaptive average pooling as rows @ x @ cols^T.
    fn adaptive_pool(&self, x: &Tensor, oh: usize, ow: usize) -> Result<Tensor> {
        let (_, _, h, w) = x.dims4()?;
        let rows = Tensor::from_vec(common::pooling_matrix(h, oh), (oh, h), &self.dev)?;
        let cols_t = Tensor::from_vec(common::pooling_matrix(w, ow), (ow, w), &self.dev)?.t()?;
        rows.broadcast_matmul(x)?.broadcast_matmul(&cols_t.contiguous()?)
    }

    fn forward(&self, x: &Tensor) -> Result<Tensor> {
        let mut taps = Vec::new();
        let mut x = self.stem.forward(x)?;
        for (i, b) in self.blocks.iter().enumerate() {
            let mut h = match &b.expand {
                Some(e) => e.forward(&x)?,
                None => x.clone(),
            };
            h = b.dw.forward(&h)?;
            h = b.project.forward(&h)?;
            x = if b.residual { common::prof("add", || x + h)? } else { h };
            if TAP_LAYERS.contains(&(i + 1)) {
                taps.push(x.clone());
            }
        }
        let s32 = self.last.forward(&x)?;
        let (_, _, h, w) = s32.dims4()?;
        let mut outs = Vec::new();
        for (branch, d) in self.psp.iter().zip(PSP_DIVISORS) {
            if d == 1 {
                outs.push(branch.forward(&s32)?);
                continue;
            }
            let pooled = common::prof("adaptive pool", || self.adaptive_pool(&s32, common::pooled_side(h, d), common::pooled_side(w, d)))?;
            let b = branch.forward(&pooled)?;
            outs.push(common::prof("resize", || b.upsample_bilinear2d(h, w, false))?);
        }
        let mut x = self.fuse.forward(&common::prof("cat", || Tensor::cat(&outs, 1))?)?;
        for ((conv, skip), tap) in self.steps.iter().zip([&taps[2], &taps[1], &taps[0]]) {
            let (_, _, th, tw) = tap.dims4()?;
            let c = conv.forward(&x)?;
            let up = common::prof("resize", || c.upsample_bilinear2d(th, tw, false))?;
            let sk = skip.forward(tap)?;
            x = common::prof("add", || up + sk)?;
        }
        self.head.forward(&x)
    }
}

fn main() -> Result<()> {
    let args = common::args();
    let shift = std::env::var("CANDLE_DW").as_deref() == Ok("shift");
    let dev = Device::Cpu;
    let net = common::load_net(&args.model);
    let model = Model::new(&net, &dev, shift)?;
    drop(net);
    let label = if shift { "candle-dwshift" } else { "candle" };
    common::bench(label, &args, || {
        let x = Tensor::from_vec(args.input.clone(), (1, 3, args.h, args.w), &dev).unwrap();
        let y = model.forward(&x).unwrap();
        common::prof("to_vec", || y.flatten_all().unwrap().to_vec1::<f32>().unwrap())
    });
    Ok(())
}
