//! The XEM6310 core through its FrontPanel endpoints, as the host drives
//! them (register map of `registers.rs`): RESET, the mask through pipe-in
//! 0x81, the wire-ins, START, bit-planes through the block-throttled
//! pipe-in 0x80, STOP, and the packet stream read in 16-byte blocks from
//! pipe-out 0xA0 — the bytes of the golden model, the last block padded
//! with zeros that FIFO_BYTES never counts; the DDR2 delay line runs on the
//! behavioural MCB, the block-RAM one leaves it idle. Also the constant
//! wire-outs the host checks.

mod common;

use rust_hdl::prelude::*;
use smartagg_hdl::designs::on_generation_stack;
use smartagg_hdl::designs::{TestXemCore, TestXemCoreOnChip};
use smartagg_hdl::pipeline::test_back_config;
use smartagg_hdl::registers::{self, control, status, wire_in, wire_out};
use smartagg_hdl::testbench::bench::{settle, Bench};
use smartagg_hdl::testbench::mcb_model::{mcb_to_port, port_to_mcb, McbModel};
use smartagg_model::config::PipelineConfig;
use smartagg_model::hot_pixel_mask::HotPixelMask;
use smartagg_model::packetiser::encode_stream;
use smartagg_model::pipeline::run;
use smartagg_model::plane::BitPlane;
use smartagg_model::registers::replay_words;

const W: usize = 16;
const H: usize = 6;

/// The host's session through the endpoints of an XEM6310 core type
/// (`$ddr2`: its delay line is in the DDR2, on the behavioural MCB; else
/// on chip, and the MCB port must stay idle).
macro_rules! through_the_endpoints {
    ($module:ident, $core:ty, $ddr2:expr) => {
        mod $module {
            use super::*;

            struct Host {
                core: Bench<$core>,
                mcb: Bench<McbModel>,
                /// Bytes read from the pipe-out.
                read: Vec<u8>,
                /// Reads issued whose words have not arrived yet.
                pending: usize,
                /// A read was issued on the last clock.
                issued: bool,
            }

            impl Host {
                fn clock(&mut self) {
                    let (u, m) = (&mut self.core.uut, &mut self.mcb.uut);
                    mcb_to_port(&m.mcb, &mut u.mcb);
                    u.sensor_empty.next = true;
                    settle(u);
                    if !$ddr2 {
                        // The on-chip core leaves the MCB port idle.
                        assert!(!u.mcb.cmd_en.val() && !u.mcb.wr_en.val() && !u.mcb.rd_en.val());
                    }
                    port_to_mcb(&u.mcb, &mut m.mcb);
                    settle(m);
                    // A read issued last clock: its word is on the data lines now.
                    if self.issued {
                        let w = u.out_data.val().to_u64() as u32;
                        self.read.extend_from_slice(&w.to_le_bytes());
                        self.pending -= 1;
                    }
                    self.issued = u.out_read.val();
                    self.core.tick();
                    self.mcb.tick();
                    let u = &mut self.core.uut;
                    u.trigger.next = 0.into();
                    u.replay_write.next = false;
                    u.mask_write.next = false;
                    u.out_read.next = false;
                }

                fn wire_out(&mut self, addr: u8) -> u32 {
                    settle(&mut self.core.uut);
                    self.core.uut.wire_out[(addr - wire_out::STATUS) as usize]
                        .val()
                        .to_u64() as u32
                }

                fn trigger(&mut self, bit: u8) {
                    self.core.uut.trigger.next = (1u64 << bit).to_bits();
                    self.clock();
                }

                /// Writes 32-bit words to a block pipe-in, a block at a time when ready;
                /// reads whatever the pipe-out offers meanwhile.
                fn write_pipe(&mut self, mask: bool, words: &[u32]) {
                    assert!(words.len().is_multiple_of(4), "whole blocks");
                    for block in words.chunks(4) {
                        loop {
                            settle(&mut self.core.uut);
                            let ready = if mask {
                                self.core.uut.mask_ready.val()
                            } else {
                                self.core.uut.replay_ready.val()
                            };
                            if ready {
                                break;
                            }
                            self.read_blocks();
                            self.clock();
                        }
                        for &w in block {
                            let u = &mut self.core.uut;
                            if mask {
                                u.mask_write.next = true;
                                u.mask_data.next = (w as u64).to_bits();
                            } else {
                                u.replay_write.next = true;
                                u.replay_data.next = (w as u64).to_bits();
                            }
                            self.clock();
                        }
                    }
                }

                /// Reads one 16-byte block if the pipe-out offers one.
                fn read_blocks(&mut self) {
                    settle(&mut self.core.uut);
                    if self.pending == 0 && self.core.uut.out_ready.val() {
                        for _ in 0..4 {
                            self.core.uut.out_read.next = true;
                            self.pending += 1;
                            self.clock();
                        }
                        self.clock();
                    }
                }
            }

            #[test]
            fn host_sees_the_model_stream_through_the_endpoints() {
                // A whole core outgrows a test thread's 2 MiB stack while it is built.
                on_generation_stack(|| {
                    let cfg = test_back_config(4, 3, 1).unwrap();
                    let mut host = Host {
                        core: Bench::new(<$core>::new(&cfg).unwrap(), |u| &mut u.clock),
                        mcb: Bench::new(McbModel::new(4, 300, 6, 20, 5), |u| &mut u.clock),
                        read: Vec::new(),
                        pending: 0,
                        issued: false,
                    };
                    // Generation words the host checks before streaming.
                    assert_eq!(host.wire_out(wire_out::VERSION), registers::version_word());
                    assert_eq!(host.wire_out(wire_out::GEOMETRY), (W | H << 16) as u32);
                    assert_eq!(
                        host.wire_out(wire_out::GENERATION),
                        5 | 4 << 8 | 3 << 16 | 4 << 24
                    );
                    assert_eq!(
                        host.wire_out(wire_out::KERNEL_CRC),
                        registers::kernel_crc(&[1, 4, 6, 4, 1])
                    );
                    assert_eq!(host.wire_out(wire_out::R_ASSOC), 1);
                    assert_eq!(host.wire_out(wire_out::MAX_N), 7);

                    // A stream with a hot pixel, as in the pipeline tests.
                    let mut rng = common::rng(9);
                    let planes = common::random_planes(&mut rng, W, H, 24, 0.08); // 24 planes = 18 blocks
                    let (mask, _) = HotPixelMask::from_pixels(W, H, &[(3, 2), (12, 4)]);
                    let mut mcfg = PipelineConfig::new(W, H, 4, vec![1, 4, 6, 4, 1], 4, 60);
                    mcfg.slots = 4;
                    mcfg.roi_size = 3;
                    mcfg.l_min = 2;
                    mcfg.l_max = 8;
                    // Hysteresis through wire-in THRESHOLD_HOLD, the field
                    // design's trim through END_TRIM.
                    mcfg.threshold_hold = 30;
                    mcfg.end_trim = 2;
                    mcfg.hot_mask = Some(mask.clone());
                    let records = run(mcfg.clone(), planes.clone()).unwrap();
                    assert!(records
                        .iter()
                        .any(|r| matches!(r, smartagg_model::record::Record::Blink(_))));
                    let want = encode_stream(&records).unwrap();

                    host.trigger(registers::trigger::RESET);
                    let mask_plane =
                        BitPlane::from_fn(W, H, |x, y| mask.is_masked(x as i64, y as i64));
                    let mut mw = replay_words(&[mask_plane]);
                    mw.resize(4, 0); // one whole block; the padding falls past the plane
                    host.write_pipe(true, &mw);
                    // START at once: it waits for the mask and the memory itself.
                    assert_eq!(
                        host.wire_out(wire_out::STATUS) & status::MEM_READY == 0,
                        $ddr2,
                        "the DDR2 calibrates, block RAM is ready at once"
                    );
                    let wi = [
                        (
                            wire_in::CONTROL,
                            control::SOURCE_REPLAY | control::MASK_ENABLE,
                        ),
                        (wire_in::N_WINDOW, 4),
                        (wire_in::THRESHOLD_INT, 60),
                        (wire_in::L_MIN, 2),
                        (wire_in::L_MAX, 8),
                        (wire_in::PLANE_PERIOD_NS, 100_000),
                        (wire_in::MASKED_PIXELS, 2),
                        (wire_in::THRESHOLD_HOLD, 30),
                        (wire_in::END_TRIM, 2),
                    ];
                    for (a, v) in wi {
                        host.core.uut.wire_in[a as usize].next = (v as u64).to_bits();
                    }
                    host.trigger(registers::trigger::START);
                    // START waits for the mask pipe to drain (just written) and
                    // the memory's calibration (300 clocks of the model); the
                    // registers' check then takes a clock.
                    let mut clocks = 0;
                    while host.wire_out(wire_out::STATUS) & status::RUNNING == 0 {
                        let st = host.wire_out(wire_out::STATUS);
                        assert_eq!(st & status::CONFIG_ERROR, 0);
                        host.clock();
                        clocks += 1;
                        assert!(clocks < 1_000, "never RUNNING");
                    }
                    host.write_pipe(false, &replay_words(&planes));
                    host.trigger(registers::trigger::STOP);
                    let mut cycles = 0;
                    while host.wire_out(wire_out::STATUS) & status::ENDED == 0
                        || host.wire_out(wire_out::FIFO_BYTES) > 0
                    {
                        host.read_blocks();
                        host.clock();
                        cycles += 1;
                        assert!(cycles < 200_000, "stream did not end");
                    }
                    let st = host.wire_out(wire_out::STATUS);
                    assert_eq!(
                        st & (status::FAULT
                            | status::OVERFLOWED
                            | status::CONFIG_ERROR
                            | status::FRAMING_ERROR),
                        0,
                        "status {st:#x}"
                    );
                    // Every byte of the model, then zero padding to a whole block.
                    let n = want.len();
                    assert!(
                        host.read.len() >= n
                            && host.read.len().is_multiple_of(16)
                            && host.read.len() - n < 16
                    );
                    assert_eq!(&host.read[..n], &want[..]);
                    assert!(host.read[n..].iter().all(|&b| b == 0));
                });
            }
        }
    };
}

through_the_endpoints!(ddr2, TestXemCore, true);
through_the_endpoints!(on_chip, TestXemCoreOnChip, false);
