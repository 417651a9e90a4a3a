use smartagg_hdl::front_half::verilog;
use smartagg_hdl::pipeline::*;
use smartagg_hdl::xem6310::Spcimager150Xem;
fn main() {
    let cfg = spcimager150_back_config().unwrap();
    std::fs::write("/tmp/gw3/xem150.v", verilog(Spcimager150Xem::new(&cfg).unwrap())).unwrap();
    let cfg = projected150_back_config().unwrap();
    std::fs::write("/tmp/gw3/proj150.v", verilog(Projected150Pipeline::new(&cfg).unwrap())).unwrap();
}
