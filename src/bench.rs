// SPDX-License-Identifier: MIT OR Apache-2.0
//! `decalbake bench`: placeholder replaced below.
