//! Deep SHAP and Kernel SHAP (being written).
