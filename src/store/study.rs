//! The study parts of the store: a study job (`[study]`) is a parent row whose `children`
//! column counts its runs, and each run a child row (an ordinary job) whose `parent` column
//! names it. The parent is never queued or claimed: it is `running` from its submission until
//! the engine completes it (with its report as its result) or cancels it. Both backends
//! implement [`StudyStore`]; the engine's coordination is in `crate::engine::study`.

use super::{StoreError, StoredResult};
use crate::status::JobView;

/// What the engine asks of the store for studies.
pub trait StudyStore {
    /// Records a study in one transaction: the parent `running` (its `total` the number of
    /// children) with its spec (JSON), and the children `queued`, each with its spec and the
    /// parent's id. False (and nothing written) when an id is taken.
    fn insert_study(
        &self,
        parent: &JobView,
        spec_json: &str,
        children: &[(JobView, String)],
    ) -> Result<bool, StoreError>;

    /// Whether `id` is a study's parent job.
    fn is_study(&self, id: &str) -> Result<bool, StoreError>;

    /// The spec (JSON) of a study's parent job; `None` when `id` is not one.
    fn study_spec(&self, id: &str) -> Result<Option<String>, StoreError>;

    /// The children of a parent job, in the order they were submitted (the reference run
    /// first, if any, then the study's runs); empty for any other job.
    fn children(&self, parent: &str) -> Result<Vec<JobView>, StoreError>;

    /// A job ended: when it is the child of a running parent, the parent's progress (`done` =
    /// its children that ended) is updated and the parent's status returned.
    fn child_ended(&self, id: &str) -> Result<Option<JobView>, StoreError>;

    /// Ends a running parent job with its status and result (its report); false when it had
    /// already ended (another worker or replica completed or cancelled it first).
    fn finish_study(
        &self,
        row: &JobView,
        result: Option<&StoredResult>,
    ) -> Result<bool, StoreError>;

    /// The running parent jobs whose children have all ended (to be completed).
    fn studies_to_finish(&self) -> Result<Vec<String>, StoreError>;
}
