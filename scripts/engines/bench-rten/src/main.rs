//! rten 0.27: the learned part of the net.
//!
//! MODEL ending in `.onnx`: the ONNX graph of the learned part, exported
//! from python/matseg/net.py (py/torch_ref.py onnx), run with `Model::run_one`.
//! Otherwise: the safetensors file, run with rten's ops-as-functions API
//! (see `functions.rs`).

mod functions;

use rten::Model;
use rten_tensor::prelude::*;
use rten_tensor::Tensor;

fn main() {
    let args = common::args();
    if args.model.ends_with(".onnx") {
        let model = Model::load_file(&args.model).expect("load onnx");
        common::bench("rten-onnx", &args, || {
            let x = Tensor::from_data(&[1, 3, args.h, args.w], args.input.clone());
            let y = model.run_one(x.view().into(), None).expect("run");
            let y: Tensor<f32> = y.try_into().expect("f32 output");
            y.into_data()
        });
    } else {
        let net = common::load_net(&args.model);
        let model = functions::Model::new(&net);
        drop(net);
        common::bench("rten-ops", &args, || {
            let x = Tensor::from_data(&[1, 3, args.h, args.w], args.input.clone());
            model.forward(x).into_data()
        });
    }
}
