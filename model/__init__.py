"""The manipulator model: the model file, and the maths written once in SymPy."""
