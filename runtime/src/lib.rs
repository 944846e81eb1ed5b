//! Streaming pre-shape classification and the Hannes serial link.
