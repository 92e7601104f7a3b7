"""Code generation: model -> float32 C through Jinja2 templates."""
