/// A file a job produced: what the export writers make and the store keeps.
#[derive(Clone, Debug, PartialEq)]
pub struct Artifact {
    pub name: String,
    pub media_type: String,
    pub bytes: Vec<u8>,
}

impl Artifact {
    pub fn new(name: &str, media_type: &str, bytes: Vec<u8>) -> Self {
        Self { name: name.to_string(), media_type: media_type.to_string(), bytes }
    }
}
