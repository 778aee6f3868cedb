"""Joint types: each one class that carries its behaviour, and the constraint
terms and equations they are made of."""
