//! Point-cloud registration (FPFH + Fast Global Registration + ICP). Filled by its own issue.
