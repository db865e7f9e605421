"""What agents make of their own camera images."""
