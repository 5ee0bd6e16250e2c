"""fogiac's Pulumi programs: one ComponentResource module per AWS resource family."""
