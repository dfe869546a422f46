"""The learned human: walk environment, AMP discriminator, training, the policy human."""
