//! The Growing Dual-Memory network (G-EM + G-SM Gamma-GWR memories). Filled by issue 2.
