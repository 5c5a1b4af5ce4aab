"""The dual-arm mobile manipulator: model loading, differential IK, controllers."""
