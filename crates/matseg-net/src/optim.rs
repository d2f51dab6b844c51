//! AdamW (Loshchilov and Hutter), with its state as named tensors so that a
//! checkpoint holds everything a resumed run needs to take exactly the same
//! next step (tch's built-in optimisers keep their moments out of reach).

use crate::checkpoint_keys::{FIRST_MOMENT, OPTIMIZER_STEPS, SECOND_MOMENT};
use crate::weights::TensorMismatch;
use tch::{nn, Kind, Tensor};

/// AdamW's constants (PyTorch's defaults for the betas and epsilon).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdamWConfig {
    /// Decay of the first moment.
    pub beta1: f64,
    /// Decay of the second moment.
    pub beta2: f64,
    /// Added to the second moment's square root.
    pub eps: f64,
    /// Decoupled weight decay (pipeline.md §8: 4e-5).
    pub weight_decay: f64,
}

impl Default for AdamWConfig {
    fn default() -> Self {
        Self {
            beta1: 0.9,
            beta2: 0.999,
            eps: 1e-8,
            weight_decay: 4e-5,
        }
    }
}

/// AdamW over every trainable variable of a `VarStore`. The variables are
/// moved into one flat buffer (each keeps its name and shape as a view of
/// it), and so are the moments and, each step, the gradients: an update is
/// about ten whole-buffer operations instead of about fourteen per variable,
/// which on a GPU are kernel launches (MobileNetV2's net has 158 variables).
#[derive(Debug)]
pub struct AdamW {
    config: AdamWConfig,
    /// Steps taken.
    steps: i64,
    /// The variables, sorted by name, with where their data start in
    /// `params` (offsets aligned to [`ALIGN`] elements).
    slots: Vec<Slot>,
    /// All trainable variables, flat.
    params: Tensor,
    /// First moments, laid out as `params`.
    m: Tensor,
    /// Second moments, laid out as `params`.
    v: Tensor,
    /// Each value's learning-rate factor, laid out as `params` (`None`:
    /// 1 everywhere).
    lr_scale: Option<Tensor>,
}

/// One trainable variable in the flat buffers.
#[derive(Debug)]
struct Slot {
    name: String,
    variable: Tensor,
    offset: i64,
    /// Zeros filling the gap after the variable up to the next aligned
    /// offset (`None`: no gap), for assembling the flat gradient.
    gap: Option<Tensor>,
}

impl Slot {
    /// This variable's part of `flat`, shaped as the variable.
    fn view(&self, flat: &Tensor) -> Tensor {
        flat.narrow(0, self.offset, self.variable.numel() as i64)
            .view(self.variable.size().as_slice())
    }
}

/// Each variable starts at a multiple of this many elements (256 bytes),
/// as separately allocated tensors do: cuDNN picks slower kernels for
/// weights that are less aligned.
const ALIGN: i64 = 64;

impl AdamW {
    /// Zero moments for the trainable variables of `vs`, whose data move
    /// into the optimizer's flat buffer (their values are kept, and later
    /// copies into them, such as loaded weights, land there too).
    pub fn new(vs: &nn::VarStore, config: AdamWConfig) -> Self {
        // Trainable variables require gradients; BatchNorm's running
        // statistics do not.
        let mut variables: Vec<(String, Tensor)> = vs
            .variables()
            .into_iter()
            .filter(|(_, t)| t.requires_grad())
            .collect();
        variables.sort_by(|a, b| a.0.cmp(&b.0));
        let device = vs.device();
        let mut total = 0;
        let mut slots = Vec::with_capacity(variables.len());
        for (name, variable) in variables {
            let numel = variable.numel() as i64;
            let gap = (ALIGN - numel % ALIGN) % ALIGN;
            slots.push(Slot {
                name,
                variable,
                offset: total,
                gap: (gap > 0).then(|| Tensor::zeros([gap], (Kind::Float, device))),
            });
            total += numel + gap;
        }
        let params = Tensor::zeros([total], (Kind::Float, device));
        for slot in &mut slots {
            let mut view = slot.view(&params);
            tch::no_grad(|| view.copy_(&slot.variable));
            slot.variable.set_data(&view);
        }
        Self {
            config,
            steps: 0,
            slots,
            m: params.zeros_like(),
            v: params.zeros_like(),
            params,
            lr_scale: None,
        }
    }

    /// Multiplies the learning rate (and so the weight decay) of every
    /// variable whose name starts with `prefix` by `scale`: 0 freezes them,
    /// 0.1 makes them learn ten times slower. Returns how many variables
    /// it applies to.
    pub fn scale_lr(&mut self, prefix: &str, scale: f64) -> usize {
        let scales = self
            .lr_scale
            .get_or_insert_with(|| self.params.ones_like())
            .shallow_clone();
        let mut scaled = 0;
        for slot in self.slots.iter().filter(|s| s.name.starts_with(prefix)) {
            let mut part = slot.view(&scales);
            let _ = tch::no_grad(|| part.fill_(scale));
            scaled += 1;
        }
        scaled
    }

    /// Back-propagates `loss` to the variables and takes one update with
    /// learning rate `lr`. The gradients are computed for this step only
    /// (nothing accumulates in the variables' `grad`).
    pub fn step(&mut self, loss: &Tensor, lr: f64) {
        let variables: Vec<&Tensor> = self.slots.iter().map(|s| &s.variable).collect();
        let grads = Tensor::run_backward(&[loss], &variables, false, false);
        let mut flat = Vec::with_capacity(2 * grads.len());
        for (g, slot) in grads.iter().zip(&self.slots) {
            flat.push(if g.defined() {
                g.reshape([-1])
            } else {
                // A variable the loss does not depend on.
                slot.variable.detach().zeros_like().reshape([-1])
            });
            if let Some(zeros) = &slot.gap {
                flat.push(zeros.shallow_clone());
            }
        }
        self.steps += 1;
        let c = self.config;
        let bias1 = 1.0 - c.beta1.powi(self.steps as i32);
        let bias2 = 1.0 - c.beta2.powi(self.steps as i32);
        tch::no_grad(|| {
            let mut g = Tensor::cat(&flat, 0);
            match &self.lr_scale {
                None => {
                    let _ = self.params.g_mul_scalar_(1.0 - lr * c.weight_decay);
                }
                Some(scale) => {
                    let decay = &self.params * scale * (lr * c.weight_decay);
                    let _ = self.params.g_sub_(&decay);
                }
            }
            let _ = self.m.lerp_(&g, 1.0 - c.beta1);
            let _ = g.square_();
            let _ = self.v.lerp_(&g, 1.0 - c.beta2);
            let mut denom = self.v.sqrt();
            let _ = denom.g_div_scalar_(bias2.sqrt());
            let _ = denom.g_add_scalar_(c.eps);
            let mut update = self.m.divide(&denom);
            let _ = update.g_mul_scalar_(lr / bias1);
            if let Some(scale) = &self.lr_scale {
                let _ = update.g_mul_(scale);
            }
            let _ = self.params.g_sub_(&update);
        });
    }

    /// The state as named tensors (`m.NAME`, `v.NAME`, `steps`: see
    /// [`crate::checkpoint_keys`]).
    pub fn state(&self) -> Vec<(String, Tensor)> {
        let mut state = vec![(
            OPTIMIZER_STEPS.to_string(),
            Tensor::from_slice(&[self.steps]).to_kind(Kind::Int64),
        )];
        for slot in &self.slots {
            state.push((format!("{FIRST_MOMENT}{}", slot.name), slot.view(&self.m)));
            state.push((format!("{SECOND_MOMENT}{}", slot.name), slot.view(&self.v)));
        }
        state
    }

    /// Restores a [`AdamW::state`]; the error names what is missing or
    /// misshapen.
    pub(crate) fn load_state(&mut self, state: &[(String, Tensor)]) -> Result<(), TensorMismatch> {
        let find = |key: &str| {
            state
                .iter()
                .find(|(n, _)| n == key)
                .map(|(_, t)| t)
                .ok_or_else(|| TensorMismatch::NoOptimizerState(key.to_string()))
        };
        self.steps = find(OPTIMIZER_STEPS)?.int64_value(&[0]);
        for slot in &self.slots {
            for (prefix, flat) in [(FIRST_MOMENT, &self.m), (SECOND_MOMENT, &self.v)] {
                let key = format!("{prefix}{}", slot.name);
                let saved = find(&key)?;
                if saved.size() != slot.variable.size() {
                    return Err(TensorMismatch::OptimizerShape {
                        name: key,
                        found: saved.size(),
                    });
                }
                let mut part = slot.view(flat);
                tch::no_grad(|| part.copy_(saved));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tch::Device;

    /// A store with two variables, `a` (2 values) and `b` (1x1).
    fn store() -> nn::VarStore {
        let vs = nn::VarStore::new(Device::Cpu);
        let _ = vs
            .root()
            .var_copy("b", &Tensor::from_slice(&[0.5f32]).view([1, 1]));
        let _ = vs
            .root()
            .var_copy("a", &Tensor::from_slice(&[1.0f32, -2.0]));
        vs
    }

    fn values(vs: &nn::VarStore, name: &str) -> Vec<f32> {
        Vec::<f32>::try_from(vs.variables()[name].reshape([-1])).unwrap()
    }

    /// loss = 3 a0 - a1 + b^2: gradients (3, -1) and 2b.
    fn loss(vs: &nn::VarStore) -> Tensor {
        let v = vs.variables();
        let a = &v["a"];
        (a * Tensor::from_slice(&[3.0f32, -1.0])).sum(Kind::Float)
            + (&v["b"] * &v["b"]).sum(Kind::Float)
    }

    /// AdamW by the book (PyTorch's formula), in f64.
    fn reference(mut x: f64, grad: impl Fn(f64) -> f64, lrs: &[f64], c: AdamWConfig) -> f64 {
        let (mut m, mut v) = (0.0, 0.0);
        for (t, &lr) in lrs.iter().enumerate() {
            let g = grad(x);
            let t = t as i32 + 1;
            x *= 1.0 - lr * c.weight_decay;
            m = c.beta1 * m + (1.0 - c.beta1) * g;
            v = c.beta2 * v + (1.0 - c.beta2) * g * g;
            let denom = v.sqrt() / (1.0 - c.beta2.powi(t)).sqrt() + c.eps;
            x -= lr / (1.0 - c.beta1.powi(t)) * m / denom;
        }
        x
    }

    #[test]
    fn steps_match_adamw_by_the_book_through_the_flat_buffer() {
        let vs = store();
        let config = AdamWConfig {
            weight_decay: 0.1,
            ..Default::default()
        };
        let mut optimizer = AdamW::new(&vs, config);
        let base = optimizer.params.data_ptr() as usize;
        for slot in &optimizer.slots {
            let offset = slot.variable.data_ptr() as usize - base;
            assert_eq!(
                offset % (4 * ALIGN as usize),
                0,
                "{} at byte {offset}",
                slot.name
            );
        }
        let lrs = [0.1, 0.05, 0.2];
        for &lr in &lrs {
            optimizer.step(&loss(&vs), lr);
        }
        let expected = [
            reference(1.0, |_| 3.0, &lrs, config),
            reference(-2.0, |_| -1.0, &lrs, config),
            reference(0.5, |b| 2.0 * b, &lrs, config),
        ];
        let got: Vec<f32> = [values(&vs, "a"), values(&vs, "b")].concat();
        for (g, e) in got.iter().zip(expected) {
            assert!((*g as f64 - e).abs() < 1e-5, "{got:?} vs {expected:?}");
        }
        // Nothing accumulates in the variables' own gradients.
        assert!(!vs.variables()["a"].grad().defined());
    }

    #[test]
    fn scaled_variables_step_as_with_a_scaled_learning_rate() {
        let vs = store();
        let config = AdamWConfig {
            weight_decay: 0.1,
            ..Default::default()
        };
        let mut optimizer = AdamW::new(&vs, config);
        assert_eq!(optimizer.scale_lr("a", 0.25), 1);
        let lrs = [0.1, 0.05, 0.2];
        for &lr in &lrs {
            optimizer.step(&loss(&vs), lr);
        }
        let quarter: Vec<f64> = lrs.iter().map(|lr| lr * 0.25).collect();
        let expected = [
            reference(1.0, |_| 3.0, &quarter, config),
            reference(-2.0, |_| -1.0, &quarter, config),
            reference(0.5, |b| 2.0 * b, &lrs, config),
        ];
        let got: Vec<f32> = [values(&vs, "a"), values(&vs, "b")].concat();
        for (g, e) in got.iter().zip(expected) {
            assert!((*g as f64 - e).abs() < 1e-5, "{got:?} vs {expected:?}");
        }
        // A scale of 0 freezes.
        let frozen = store();
        let mut optimizer = AdamW::new(&frozen, config);
        optimizer.scale_lr("", 0.0);
        optimizer.step(&loss(&frozen), 0.1);
        assert_eq!(values(&frozen, "a"), [1.0, -2.0]);
    }

    #[test]
    fn copies_into_the_variables_after_creation_are_optimised() {
        let vs = store();
        let mut optimizer = AdamW::new(&vs, AdamWConfig::default());
        let mut a = vs.variables()["a"].shallow_clone();
        tch::no_grad(|| a.copy_(&Tensor::from_slice(&[10.0f32, 20.0])));
        optimizer.step(&loss(&vs), 0.5);
        // The first Adam step moves each value by about lr against its
        // gradient's sign.
        let after = values(&vs, "a");
        assert!(
            (after[0] - 9.5).abs() < 0.01 && (after[1] - 20.5).abs() < 0.01,
            "{after:?}"
        );
    }

    #[test]
    fn a_restored_state_takes_the_same_next_step() {
        let (first, second) = (store(), store());
        let mut a = AdamW::new(&first, AdamWConfig::default());
        a.step(&loss(&first), 0.1);
        let mut b = AdamW::new(&second, AdamWConfig::default());
        for (name, mut variable) in second.variables() {
            tch::no_grad(|| variable.copy_(&first.variables()[&name]));
        }
        b.load_state(&a.state()).unwrap();
        a.step(&loss(&first), 0.1);
        b.step(&loss(&second), 0.1);
        for name in ["a", "b"] {
            assert_eq!(values(&first, name), values(&second, name), "{name}");
        }
        let mut state = a.state();
        state.retain(|(n, _)| n != "v.b");
        assert_eq!(
            b.load_state(&state).unwrap_err().to_string(),
            "optimizer state has no v.b"
        );
    }
}
