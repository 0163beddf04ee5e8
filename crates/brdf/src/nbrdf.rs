//! nbrdf
