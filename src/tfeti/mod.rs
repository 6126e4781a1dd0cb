//! Total FETI: per-subdomain operators and the dual problem.

pub mod dual;
pub mod floating;
pub mod subdomain;
