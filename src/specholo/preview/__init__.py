"""Pictures of what a viewer sees, from the same glint physics as verification."""
