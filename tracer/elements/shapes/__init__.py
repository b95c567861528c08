"""The feature shapes of a micro-structured face (`tracer.elements.microstructure`): one module per shape beside its
contract (`base`), registered in `dispatch`."""
