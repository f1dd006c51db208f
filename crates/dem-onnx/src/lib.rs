//! ONNX for the dem-* tools (being written).
