//! The layers the net is made of, on rten's operators: convolutions with
//! their BatchNorm folded in, activations, resizing, pooling and the
//! per-pixel normalisations. Tensors are NCHW with one image (N = 1).

use crate::weights::Weights;
use matseg_model::ModelError;
use rayon::prelude::*;
use rten::ops::{self, CoordTransformMode, NearestMode, Padding, ResizeMode, ResizeTarget};
use rten::BufferPool;
use rten_simd::SimdUnaryOp;
use rten_tensor::prelude::*;
use rten_tensor::{NdTensor, Tensor};

/// Elements an activation handles per parallel task.
const CHUNK: usize = 16 * 1024;

/// BatchNorm's epsilon (PyTorch's default, which the net trains with).
const BATCH_NORM_EPS: f64 = 1e-5;

/// What follows a convolution.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Activation {
    /// Nothing.
    None,
    /// min(max(x, 0), 6): MobileNetV2's.
    Relu6,
    /// x Φ(x) with the exact normal CDF: the head's and ConvNeXt's.
    Gelu,
}

/// The shape of a convolution: `c_in` to `c_out` channels, a `k x k`
/// kernel, its stride and groups; padding is `k / 2` unless `valid`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ConvShape {
    pub c_in: usize,
    pub c_out: usize,
    pub k: usize,
    pub stride: usize,
    pub groups: usize,
    /// No padding (ConvNeXt's patchifying convolutions).
    pub valid: bool,
}

impl ConvShape {
    /// A `k x k` convolution of stride 1, one group, same padding.
    pub(crate) fn same(c_in: usize, c_out: usize, k: usize) -> Self {
        Self {
            c_in,
            c_out,
            k,
            stride: 1,
            groups: 1,
            valid: false,
        }
    }

    /// The shape of its weight tensor.
    fn weight_shape(&self) -> [usize; 4] {
        [self.c_out, self.c_in / self.groups, self.k, self.k]
    }
}

/// A convolution with a bias (BatchNorm folded in where there is one) and
/// its activation.
pub(crate) struct Conv {
    weight: Tensor<f32>,
    bias: NdTensor<f32, 1>,
    stride: usize,
    padding: usize,
    groups: usize,
    activation: Activation,
}

impl Conv {
    /// The convolution `conv` (a weight without bias) followed by the
    /// BatchNorm `bn` in inference mode, folded into one: each output
    /// channel's weights times γ/√(σ² + ε), its bias β − μγ/√(σ² + ε)
    /// (computed in f64).
    pub(crate) fn folded(
        weights: &Weights,
        conv: &str,
        bn: &str,
        shape: ConvShape,
        activation: Activation,
    ) -> Result<Self, ModelError> {
        let c = [shape.c_out];
        let w = weights.get(&format!("{conv}.weight"), &shape.weight_shape())?;
        let gamma = weights.get(&format!("{bn}.weight"), &c)?;
        let beta = weights.get(&format!("{bn}.bias"), &c)?;
        let mean = weights.get(&format!("{bn}.running_mean"), &c)?;
        let var = weights.get(&format!("{bn}.running_var"), &c)?;
        let per_channel = w.len() / shape.c_out;
        let mut weight = w;
        let mut bias = vec![0f32; shape.c_out];
        for o in 0..shape.c_out {
            let scale = f64::from(gamma[o]) / (f64::from(var[o]) + BATCH_NORM_EPS).sqrt();
            for v in &mut weight[o * per_channel..(o + 1) * per_channel] {
                *v = (f64::from(*v) * scale) as f32;
            }
            bias[o] = (f64::from(beta[o]) - f64::from(mean[o]) * scale) as f32;
        }
        Ok(Self::new(weight, bias, shape, activation))
    }

    /// The convolution `name` with its own bias (`name.weight`,
    /// `name.bias`).
    pub(crate) fn with_bias(
        weights: &Weights,
        name: &str,
        shape: ConvShape,
        activation: Activation,
    ) -> Result<Self, ModelError> {
        let weight = weights.get(&format!("{name}.weight"), &shape.weight_shape())?;
        let bias = weights.get(&format!("{name}.bias"), &[shape.c_out])?;
        Ok(Self::new(weight, bias, shape, activation))
    }

    /// A convolution from its values.
    pub(crate) fn new(
        weight: Vec<f32>,
        bias: Vec<f32>,
        shape: ConvShape,
        activation: Activation,
    ) -> Self {
        Self {
            weight: Tensor::from_data(&shape.weight_shape(), weight),
            bias: NdTensor::from_data([shape.c_out], bias),
            stride: shape.stride,
            padding: if shape.valid { 0 } else { shape.k / 2 },
            groups: shape.groups,
            activation,
        }
    }

    /// The convolution and its activation applied to `x`.
    pub(crate) fn forward(&self, pool: &BufferPool, x: &Tensor<f32>) -> Tensor<f32> {
        let p = self.padding;
        let mut y: Tensor<f32> = ops::conv(
            pool,
            x.view(),
            self.weight.view(),
            Some(self.bias.view()),
            Padding::from([p, p, p, p]),
            self.groups,
            &[self.stride, self.stride],
            &[1, 1],
        )
        .expect("a convolution of the shape the net was built for");
        activate(&mut y, self.activation);
        y
    }
}

/// Applies `activation` to `x` in place, in parallel chunks.
pub(crate) fn activate(x: &mut Tensor<f32>, activation: Activation) {
    let data = x.data_mut().expect("an operator's output is contiguous");
    match activation {
        Activation::None => {}
        Activation::Relu6 => data
            .par_chunks_mut(CHUNK)
            .for_each(|c| c.iter_mut().for_each(|v| *v = v.clamp(0.0, 6.0))),
        Activation::Gelu => data
            .par_chunks_mut(CHUNK)
            .for_each(|c| rten_vecmath::Gelu {}.map_mut(c)),
    }
}

/// An interleaved RGB image of `width x height` pixels as a tensor
/// `[1, 3, height, width]` of `value(channel, level)`.
pub(crate) fn rgb_planes(
    rgb: &[u8],
    width: usize,
    height: usize,
    value: impl Fn(usize, u8) -> f32,
) -> Tensor<f32> {
    let n = width * height;
    let mut planes = vec![0f32; 3 * n];
    for (i, pixel) in rgb.chunks_exact(3).enumerate() {
        for (c, &level) in pixel.iter().enumerate() {
            planes[c * n + i] = value(c, level);
        }
    }
    Tensor::from_data(&[1, 3, height, width], planes)
}

/// `a + b`, of one shape.
pub(crate) fn add(pool: &BufferPool, a: &Tensor<f32>, b: &Tensor<f32>) -> Tensor<f32> {
    ops::add(pool, a.view(), b.view()).expect("two tensors of one shape")
}

/// Bilinear resize of `x` to `height x width` with half-pixel centres
/// (PyTorch's `align_corners=False`).
pub(crate) fn resize(
    pool: &BufferPool,
    x: &Tensor<f32>,
    height: usize,
    width: usize,
) -> Tensor<f32> {
    let s = x.shape();
    if (s[2], s[3]) == (height, width) {
        return x.clone();
    }
    let sizes = NdTensor::from([s[0] as i32, s[1] as i32, height as i32, width as i32]);
    ops::resize(
        pool,
        x.view(),
        ResizeTarget::Sizes(sizes.view()),
        ResizeMode::Linear,
        CoordTransformMode::PytorchHalfPixel,
        NearestMode::default(),
    )
    .expect("a resize of an NCHW tensor")
}

/// The `n_out x n_in` matrix of PyTorch's adaptive average pooling along
/// one axis: output `i` is the mean of inputs `floor(i n / o)` to
/// `ceil((i + 1) n / o)`, row by row.
fn pooling_matrix(n_in: usize, n_out: usize) -> Vec<f32> {
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

/// PyTorch's adaptive average pooling of `x` to `height x width`, as two
/// matrix products (rows, then columns).
pub(crate) fn adaptive_average_pool(
    pool: &BufferPool,
    x: &Tensor<f32>,
    height: usize,
    width: usize,
) -> Tensor<f32> {
    let s = x.shape();
    let (h, w) = (s[2], s[3]);
    let rows = Tensor::from_data(&[height, h], pooling_matrix(h, height));
    let columns = Tensor::from_data(&[width, w], pooling_matrix(w, width));
    let y: Tensor<f32> = ops::matmul(pool, rows.view(), x.view(), None).expect("pooling rows");
    ops::matmul(pool, y.view(), columns.transposed(), None).expect("pooling columns")
}

/// Scales each pixel's channel vector of `x` (`[1, C, H, W]`) to length
/// `length` (norms below 1e-12 taken as 1e-12, as the net does).
pub(crate) fn normalise_pixels(x: &mut Tensor<f32>, length: f32) {
    let s = x.shape();
    let hw = s[2] * s[3];
    let data = x.data_mut().expect("an operator's output is contiguous");
    let mut squares = vec![0f32; hw];
    for plane in data.chunks_exact(hw) {
        for (sum, v) in squares.iter_mut().zip(plane) {
            *sum += v * v;
        }
    }
    let scales: Vec<f32> = squares
        .iter()
        .map(|s| length / s.sqrt().max(1e-12))
        .collect();
    data.par_chunks_exact_mut(hw).for_each(|plane| {
        for (v, scale) in plane.iter_mut().zip(&scales) {
            *v *= scale;
        }
    });
}

/// LayerNorm over the channels of each pixel of `x` (`[1, C, H, W]`) with
/// per-channel `scale` and `bias`: ConvNeXt's.
pub(crate) fn layer_norm_channels(x: &mut Tensor<f32>, scale: &[f32], bias: &[f32], eps: f32) {
    let s = x.shape();
    let (c, hw) = (s[1], s[2] * s[3]);
    let data = x.data_mut().expect("an operator's output is contiguous");
    let mut mean = vec![0f32; hw];
    for plane in data.chunks_exact(hw) {
        for (m, v) in mean.iter_mut().zip(plane) {
            *m += v;
        }
    }
    mean.iter_mut().for_each(|m| *m /= c as f32);
    let mut variance = vec![0f32; hw];
    for plane in data.chunks_exact(hw) {
        for ((s, v), m) in variance.iter_mut().zip(plane).zip(&mean) {
            *s += (v - m) * (v - m);
        }
    }
    let inverse: Vec<f32> = variance
        .iter()
        .map(|v| 1.0 / (v / c as f32 + eps).sqrt())
        .collect();
    data.par_chunks_exact_mut(hw)
        .zip(scale.par_iter().zip(bias))
        .for_each(|(plane, (&g, &b))| {
            for ((v, m), i) in plane.iter_mut().zip(&mean).zip(&inverse) {
                *v = (*v - m) * i * g + b;
            }
        });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn adaptive_pooling_averages_pytorch_windows() {
        // 5 inputs to 2 outputs: windows 0..3 and 2..5, overlapping.
        let m = pooling_matrix(5, 2);
        let third = 1.0 / 3.0;
        assert_eq!(
            m,
            [third, third, third, 0.0, 0.0, 0.0, 0.0, third, third, third]
        );
        let pool = BufferPool::new();
        let x = Tensor::from_data(&[1, 1, 2, 4], vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0]);
        let y = adaptive_average_pool(&pool, &x, 1, 2);
        assert_eq!(y.shape(), [1, 1, 1, 2]);
        assert_eq!(y.to_vec(), [3.5, 5.5]);
    }

    #[test]
    fn pixels_are_scaled_to_the_length_asked() {
        let mut x = Tensor::from_data(&[1, 2, 1, 3], vec![3.0, 0.0, 1.0, 4.0, 0.0, 0.0]);
        normalise_pixels(&mut x, 2.0);
        assert_eq!(x.to_vec(), [1.2, 0.0, 2.0, 1.6, 0.0, 0.0]);
    }

    #[test]
    fn layer_norm_centres_and_scales_each_pixel() {
        // Pixel 0 has channels 1 and 3, pixel 1 has 5 and 7: both become
        // -1 and 1, then channel 1 is scaled by 2 and moved by 10.
        let mut x = Tensor::from_data(&[1, 2, 1, 2], vec![1.0, 5.0, 3.0, 7.0]);
        layer_norm_channels(&mut x, &[1.0, 2.0], &[0.0, 10.0], 0.0);
        assert_eq!(x.to_vec(), [-1.0, -1.0, 12.0, 12.0]);
    }
}
