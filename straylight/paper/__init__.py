"""The seed paper's scenarios and figures, reproduced from the same model the survey uses."""
