//! Data preparation (the thesis's chapter 5 and sections 6.3-6.4): the
//! library side of dem-filter, dem-pair, dem-clean-pallet and dem-fill-nans.

pub mod fill;
pub mod filter;
pub mod pair;
pub mod pallet;
pub mod stream;
