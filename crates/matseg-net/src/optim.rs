//! AdamW (Loshchilov and Hutter), with its state as named tensors so that a
//! checkpoint holds everything a resumed run needs to take exactly the same
//! next step (tch's built-in optimisers keep their moments out of reach).

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
    /// Decoupled weight decay (SPEC 8: 4e-5).
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

/// AdamW over every trainable variable of a `VarStore`.
#[derive(Debug)]
pub struct AdamW {
    config: AdamWConfig,
    /// Steps taken.
    steps: i64,
    /// (name, parameter, first moment, second moment), sorted by name.
    slots: Vec<(String, Tensor, Tensor, Tensor)>,
}

impl AdamW {
    /// Zero moments for the trainable variables of `vs`.
    pub fn new(vs: &nn::VarStore, config: AdamWConfig) -> Self {
        // Trainable variables require gradients; BatchNorm's running
        // statistics do not.
        let mut slots: Vec<(String, Tensor, Tensor, Tensor)> = vs
            .variables()
            .into_iter()
            .filter(|(_, t)| t.requires_grad())
            .map(|(name, t)| {
                let zeros = || t.zeros_like().detach();
                (name, t.shallow_clone(), zeros(), zeros())
            })
            .collect();
        slots.sort_by(|a, b| a.0.cmp(&b.0));
        Self {
            config,
            steps: 0,
            slots,
        }
    }

    /// One update with learning rate `lr` from the gradients in place; then
    /// clears the gradients.
    pub fn step(&mut self, lr: f64) {
        self.steps += 1;
        let c = self.config;
        let bias1 = 1.0 - c.beta1.powi(self.steps as i32);
        let bias2 = 1.0 - c.beta2.powi(self.steps as i32);
        tch::no_grad(|| {
            for (_, p, m, v) in &mut self.slots {
                let g = p.grad();
                if !g.defined() {
                    continue;
                }
                let _ = p.g_mul_scalar_(1.0 - lr * c.weight_decay);
                let _ = m.g_mul_scalar_(c.beta1);
                let _ = m.g_add_(&(&g * (1.0 - c.beta1)));
                let _ = v.g_mul_scalar_(c.beta2);
                let _ = v.g_add_(&(&g * &g * (1.0 - c.beta2)));
                let denom = (&*v / bias2).sqrt() + c.eps;
                let _ = p.g_sub_(&(&*m / &denom * (lr / bias1)));
                let _ = p.grad().zero_();
            }
        });
    }

    /// Clears the gradients without a step (a skipped batch).
    pub fn zero_grad(&mut self) {
        for (_, p, _, _) in &mut self.slots {
            let mut g = p.grad();
            if g.defined() {
                let _ = g.zero_();
            }
        }
    }

    /// The state as named tensors (`m.NAME`, `v.NAME`, `steps`).
    pub fn state(&self) -> Vec<(String, Tensor)> {
        let mut state = vec![(
            "steps".to_string(),
            Tensor::from_slice(&[self.steps]).to_kind(Kind::Int64),
        )];
        for (name, _, m, v) in &self.slots {
            state.push((format!("m.{name}"), m.shallow_clone()));
            state.push((format!("v.{name}"), v.shallow_clone()));
        }
        state
    }

    /// Restores a [`AdamW::state`]; the error names what is missing or
    /// misshapen.
    pub fn load_state(&mut self, state: &[(String, Tensor)]) -> Result<(), String> {
        let find = |key: &str| {
            state
                .iter()
                .find(|(n, _)| n == key)
                .map(|(_, t)| t)
                .ok_or_else(|| format!("optimizer state has no {key}"))
        };
        self.steps = find("steps")?.int64_value(&[0]);
        for (name, _, m, v) in &mut self.slots {
            for (prefix, slot) in [("m", &mut *m), ("v", &mut *v)] {
                let key = format!("{prefix}.{name}");
                let saved = find(&key)?;
                if saved.size() != slot.size() {
                    return Err(format!(
                        "optimizer state {key} has shape {:?}",
                        saved.size()
                    ));
                }
                tch::no_grad(|| slot.copy_(saved));
            }
        }
        Ok(())
    }
}
