"""Light transport: the forward photon kernels (`forward`), the backward paths (`backward`), the estimate of batch
means and what accuracy costs (`estimate`), the rounds of batches and stop rules (`rounds`), and the tessellation
error budget of an answer (`tessellation_error`)."""
