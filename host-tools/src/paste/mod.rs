//! Paste (clay, food, cementitious) printing: simulated growth, time-based jobs and the cure
//! check of a job's layer times.

mod bins;
pub mod cure;
pub mod cure_report;
pub mod grow;
pub mod timebased;
pub mod window;
