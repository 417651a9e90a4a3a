use smartagg_hdl::front_half::verilog;
use smartagg_hdl::pipeline::{test_back_config, TestPipeline};
fn main() {
    let cfg = test_back_config(4, 3, 1).unwrap();
    let v = verilog(TestPipeline::new(&cfg).unwrap());
    std::fs::write("/tmp/tp/top.v", v).unwrap();
}
